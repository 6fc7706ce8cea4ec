// Step 1 of type merging (type_merging.h): the box hierarchy. Which boxes of cubes are
// tested, in which order, and with which shapes.
//
// Blocks of B × B × B cubes (block_dims: B = block_cubes, aligned to the piece; cut by the
// piece's and the lattice's ends; B/2 along an axis whose step is at least √2 times the
// finest) are tested bottom up: each 2 × 2 × 2 block (or, if it fails, each of its two layers
// 2 × 2 × 1, or each of their rows 2 × 1 × 1, or each of their cubes alone, which is
// re-triangulated for shape, not reduced), then every block whose parts all passed, from its
// parts' disks (DiskTest::test_parts), which then replaces them if it passes too. A block's
// parts halve it along the axes it is longest along in millimetres (children_of), so blocks
// grow towards cubes in millimetres, not in voxels. Components that fail keep their
// marching-cubes triangles (emitted into `kept`); disks that pass are recorded in the store,
// a composed disk with the parts it may fall back to.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/marching_cubes.h"
#include "core/merge/disk_store.h"
#include "core/merge/disk_test.h"
#include "core/merge/geometry.h"
#include "core/mesh.h"
#include "core/type_merging.h"
#include "core/volume.h"

namespace typemerge::core::merge {

// A piece's surface as marching cubes made it: index-space mesh, and its boundary cubes in
// scan order (z, y, x), each cube's triangles from its first_triangle to the next cube's.
struct PieceSurface {
  const TriangleMesh& mesh;
  std::span<const BoundaryCube> cubes;

  TriangleRun triangles_of(std::uint32_t cube) const {
    const std::uint32_t end = cube + 1 < cubes.size()
                                  ? cubes[cube + 1].first_triangle
                                  : static_cast<std::uint32_t>(mesh.triangles.size());
    return {cubes[cube].first_triangle, end};
  }
};

// The blocks' edges in cubes: block_cubes along each axis, or, with blocks_follow_spacing,
// half that along an axis whose step is at least √2 times the finest, so blocks are closer to
// cubes in millimetres (3 mm slices over 1.07 mm pixels: 8 × 8 × 4 cubes, 8.6 × 8.6 × 12 mm).
Dims block_dims(const IndexToPatient& geometry, const MergeOptions& options);

// The edges of a block's children: halved along the axes it is longest along in millimetres
// (`spacing`: mm per cube along each axis; within a factor √2 of the longest; never below 2
// cubes), so on thick slices a 2 × 2 × 2 block grows to 4 × 4 × 2 before 8 × 8 × 4. An axis
// not halved keeps its edge.
Dims children_of(const Dims& dims, const std::array<double, 3>& spacing);

// Tests every block of `block` cubes of the piece's lattice box `lattice` that holds the
// cubes from `first_cube` on, in scan order of the blocks (z, y, x), their halves in the same
// order: passing disks into `store`, the triangles of what fails into `kept`, rejections and
// nothing else into `stats`. The cubes before `first_cube` must fill whole layers of blocks
// (so a caller can test layer after layer of blocks as marching cubes makes them).
void test_blocks(const PieceSurface& piece, const Box& lattice, const Dims& block,
                 const std::array<double, 3>& spacing, DiskTest& test, DiskStore& store,
                 std::vector<Triangle>& kept, MergeStats& stats, std::size_t first_cube = 0);

}  // namespace typemerge::core::merge
