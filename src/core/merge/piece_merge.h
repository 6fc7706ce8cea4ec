// One piece of type merging (type_merging.h): marching cubes over its cube layers, the three
// steps of the merge, and the compaction that keeps the vertices still used; then the join of
// merged pieces at their seams, in order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/marching_cubes.h"
#include "core/merge/disk_store.h"
#include "core/merge/geometry.h"
#include "core/mesh.h"
#include "core/type_merging.h"
#include "core/volume.h"

namespace typemerge::core::merge {

// One piece, merged and compacted.
struct MergedPiece {
  TriangleMesh mesh;
  std::size_t shared = 0;     // its first `shared` vertices are the piece below's top slice
  std::vector<VertexId> top;  // its top slice's vertices (ids in `mesh`), in seam order
  MergeStats stats;
  AmbiguityStats ambiguity;
};

// What a thread reuses from piece to piece: the piece's marching-cubes surface and step 1's
// disk store (about 55 bytes a marching-cubes triangle). Emptied by each piece, their arrays
// keep their capacity, so later pieces write into pages already mapped instead of faulting in
// fresh ones (docs/benchmarks.md: most of a conversion's page faults were these).
struct PieceScratch {
  detail::SurfacePiece surface;
  DiskStore store;
};

// Cube layers [first, last) of the volume, extracted and merged: step 1 (blocks.h, with
// disk_test.h), step 2 (loop_thinning.h), step 3 (disk_triangulation.h), then compacted
// (vertex order kept, so the seam's shared vertices stay first and in order). Normals (when
// extract.vertex_normals) only for the vertices kept. Throws std::logic_error if a seam
// vertex were dropped (it cannot be: seam vertices lie on block faces no second disk shares).
// expected_vertices: an estimate of marching cubes' vertices in the piece, to size its
// outputs (detail::extract_layers; < 0: none).
// `scratch`: reused between pieces (one per concurrent piece).
MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const MergeOptions& options, std::int64_t first, std::int64_t last,
                        PieceScratch& scratch, double expected_vertices = -1.0);

// Appends a merged piece to `out`, joining its shared vertices to `seam` (the output ids of
// the top slice of the piece appended before it), and makes `seam` its own top slice.
// Throws std::length_error beyond 32-bit vertex ids.
void append_piece(TriangleMesh& out, const MergedPiece& piece, std::vector<VertexId>& seam);

}  // namespace typemerge::core::merge
