// Step 1's test (type_merging.h): the marching-cubes surface inside a box → its components,
// each a disk that may be re-triangulated from its loop, or the reason it is not.
//
// A component passes when it
//  * is one disk (kTopology otherwise): Euler characteristic 1 and one boundary loop, the loop
//    being its edges that lie on the box's faces (every other edge has a triangle on each
//    side), at least three of them, closing into one cycle;
//  * faces one way (kFacing): every triangle's area vector has a positive component along the
//    disk's mean normal n (the normalised sum of its area vectors);
//  * is flat (kFlatness): its vertices lie in a slab n·p ∈ [t, t + w] that spans no more than
//    ε (tolerance.h: w ≤ ε in voxels, w·|A n| ≤ ε in millimetres);
//  * is separated from every other component of the box by its slab (kSeparation): all of
//    each other's vertices on one side of it, so their convex hulls do not meet;
//  * has a simple outline (kOutline): its loop projected along n is simple and
//    counter-clockwise, so the projection is one-to-one on the disk.
// A vertex with two loop edges leaving it pinches the surface: then the box fails as a whole
// (one kTopology), before components are formed.
//
// test_parts() runs the same tests on a block made of disks that passed already (its parts),
// from their loops, area vectors and vertices instead of their triangles: each part is a
// closed disk bounded by its loop, so the block's surface is a complex of loop vertices, loop
// edges and parts, whose Euler characteristic is V − E + F over those; a loop edge with both
// ends on one face of the block is on the block's loop, any other lies on a face two parts
// share, and each of the two has it (once per direction). Area vectors are stored in float: a
// margin of 1e-6 of the area, above float's rounding (< 4e-7 of it), keeps facing as strict as
// in double.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/merge/disk_store.h"
#include "core/merge/geometry.h"
#include "core/merge/local_table.h"
#include "core/merge/loop_triangulation.h"
#include "core/merge/tolerance.h"
#include "core/type_merging.h"

namespace typemerge::core::merge {

enum class DiskVerdict : std::uint8_t { kDisk, kTopology, kFacing, kFlatness, kOutline, kSeparation };

// Triangle ids [first, end) of the piece: a cube's triangles (marching cubes stores them so).
struct TriangleRun {
  std::uint32_t first = 0;
  std::uint32_t end = 0;
};

// A component of a box's surface and what its tests found.
struct Component {
  std::size_t vertices = 0;
  std::size_t faces = 0;
  std::size_t loop_edges = 0;
  std::size_t inner_half_edges = 0;  // test_parts: its parts' loop edges inside the block
  std::uint32_t loop_start = 0;      // a local loop vertex
  std::uint32_t loop_first = 0;      // its loop's start in the test's loop list
  P3 normal{0, 0, 0};
  P3 area{0, 0, 0};  // the sum of its triangles' area vectors (normal, before normalising)
  double low = std::numeric_limits<double>::max();
  double high = std::numeric_limits<double>::lowest();
  std::uint32_t disk = kNone;
  DiskVerdict verdict = DiskVerdict::kDisk;
};

// What test_parts makes of a block whose every component passed: its disks, their loops,
// their triangles with area vectors (empty when in_place), their vertices (each once), with
// offsets relative to these lists; and per part, its component and where its triangles start
// within its disk's.
struct ComposedBlock {
  std::vector<MergedDisk> disks;
  std::vector<VertexId> loops;
  std::vector<std::uint32_t> triangles;
  std::vector<std::array<float, 3>> areas;
  std::vector<VertexId> vertices;
  std::vector<std::uint32_t> part_component;
  std::vector<std::uint32_t> part_offset;
  // One disk, whose triangles are its parts', in their order, where they already lie in the
  // store (most blocks): nothing to copy.
  bool in_place = false;
};

class DiskTest {
 public:
  // For the piece's marching-cubes surface (positions in index space, triangles), slabs that
  // span no more than the tolerance; `table` and `outline` are scratch shared with other steps.
  DiskTest(std::span<const Position> positions, std::span<const Triangle> triangles,
           const Tolerance& tolerance, LocalTable& table, LoopTriangulator& outline)
      : positions_(positions),
        triangles_(triangles),
        tolerance_(tolerance),
        table_(table),
        outline_(outline) {}

  // Tests the components of the triangles `runs` inside `box`, counting each rejection in
  // `stats`; returns whether every component is a disk (false at once when pinched).
  bool test_triangles(std::span<const TriangleRun> runs, const Box& box, MergeStats& stats);
  // test_triangles for a box whose marching-cubes surface in `runs` is known to be one
  // connected piece (blocks.cpp's one_connected_surface): the same verdict, disk and counts,
  // bit for bit, without the union-find, and with facing and flatness first, from the
  // triangles alone, so that a box that is not flat (most that fail) is rejected before its
  // vertices are numbered. record() then keeps all its triangles, as after a pinch.
  bool test_one_piece(std::span<const TriangleRun> runs, const Box& box, MergeStats& stats);

  // The components of the last test_triangles (empty when it was pinched).
  std::span<const Component> components() const { return components_; }

  // After test_triangles: appends each passing component to `store` as a disk of block edge
  // `size` (with its loop, triangles, area vectors and vertices), and the triangles of the
  // others (all of them when pinched) to `kept`, in their order.
  void record(const Box& box, std::int32_t size, DiskStore& store, std::vector<Triangle>& kept);

  // The same tests on the block `box` made of the disks store.disks[first_part, end); on
  // success (every component passes) its disks in `out`, else false and `out` unspecified.
  bool test_parts(const DiskStore& store, std::size_t first_part, const Box& box,
                  std::int32_t size, MergeStats& stats, ComposedBlock& out);

 private:
  // A marching-cubes triangle of the box, by local corners, with its area vector.
  struct LocalTriangle {
    std::array<std::uint32_t, 3> corner;
    std::uint32_t id;
    P3 area;
  };
  void number_components();
  // Its area vector kept, its normal made unit; false when the area vector is zero.
  static bool normalise(Component& c);
  // Whether a component's counts and loop make it one disk.
  bool one_disk(const Component& c) const;
  bool append_simple_loop(Component& c, const Box& box, std::vector<VertexId>& loops);

  std::span<const Position> positions_;
  std::span<const Triangle> triangles_;
  Tolerance tolerance_;
  LocalTable& table_;
  LoopTriangulator& outline_;
  std::span<const TriangleRun> runs_;  // of the last test_triangles
  bool pinched_ = false;  // or failed before its vertices were numbered: keep every triangle
  std::vector<std::uint32_t> component_of_;  // per local vertex
  std::vector<LocalTriangle> local_triangles_;
  std::vector<Component> components_;
  std::vector<unsigned> separated_;
  std::vector<VertexId> loop_;  // test_triangles' loops, at each component's loop_first
};

}  // namespace typemerge::core::merge
