// One piece of type merging (type_merging.h): marching cubes over its cube layers, the three
// steps of the merge, and the compaction that keeps the vertices still used; then the join of
// merged pieces at their seams, in order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/marching_cubes.h"
#include "core/merge/disk_store.h"
#include "core/merge/geometry.h"
#include "core/merge/local_table.h"
#include "core/merge/loop_thinning.h"
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

// What a thread reuses from piece to piece: the piece's marching-cubes surface (with the
// extractor's slice arrays), step 1's disk store and block table, step 2's loop owners and
// vertex states, the merged triangles and the compaction's ids (about 75 bytes a
// marching-cubes triangle). Emptied by each piece, their arrays keep their capacity, so later
// pieces write into pages already mapped instead of faulting in fresh ones
// (docs/benchmarks.md: a page fault costs microseconds on virtual machines, and most of a
// conversion's were these).
struct PieceScratch {
  detail::SurfacePiece surface;
  DiskStore store;
  LocalTable table;
  LoopOwners::Arrays owners;
  std::vector<std::uint8_t> state;
  std::vector<Triangle> made;       // step 3's new triangles
  std::vector<Triangle> triangles;  // the merged piece's, before compaction
  std::vector<VertexId> new_id;
  // Arrays for the merged piece's mesh, e.g. a consumed piece's (type_merging.cpp hands them
  // back): merge_piece writes its mesh into them.
  TriangleMesh output;
  // False for the scratch's last piece: the extractor's slice arrays and the merge's
  // per-vertex arrays (table, owners, state, made) are then freed as soon as the piece is done
  // with them, so the last pieces (made while the output is at its largest) hold no more than
  // they need.
  bool keep = true;

  // Frees the arrays `keep` is about.
  void release_merge_arrays();
};

// Cube layers [first, last) of the volume, extracted and merged: step 1 (blocks.h, with
// disk_test.h), step 2 (loop_thinning.h), step 3 (disk_triangulation.h), then compacted
// (vertex order kept, so the seam's shared vertices stay first and in order). Normals (when
// extract.vertex_normals) only for the vertices kept. Throws std::logic_error if a seam
// vertex were dropped (it cannot be: seam vertices lie on block faces no second disk shares).
// expected_vertices: an estimate of marching cubes' vertices in the piece, to size its
// outputs (detail::extract_layers; < 0: none).
// `scratch`: reused between pieces (one per concurrent piece). `reads_below`, when set, is
// called with `below` rising as the piece stops reading the volume's slices below it (slice
// numbers of the volume): as its marching cubes passes them, and once with the volume's slice
// count when it has read its last sample (after its marching cubes; after its vertices'
// normals when extract.vertex_normals, with no call before).
MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const MergeOptions& options, std::int64_t first, std::int64_t last,
                        PieceScratch& scratch, double expected_vertices = -1.0,
                        const std::function<void(std::int64_t below)>& reads_below = nullptr);

// Appends a merged piece to `out`, joining its shared vertices to `seam` (the output ids of
// the top slice of the piece appended before it), and makes `seam` its own top slice.
// Throws std::length_error beyond 32-bit vertex ids.
void append_piece(TriangleMesh& out, const MergedPiece& piece, std::vector<VertexId>& seam);

}  // namespace typemerge::core::merge
