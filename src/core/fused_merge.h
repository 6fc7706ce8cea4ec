// Fused type merging: marching cubes and the merge of planar patches in one scan of the
// lattice, in windows of a few cube layers (the paper's streaming, Oh & Park 1996 §4), with
// the merged triangles emitted directly. It replaces the post-pass of checked half-edge
// collapses (which could not reach marching cubes' speed and let stretched fans cross a
// neighbouring sheet of surface).
//
// What it does. The lattice is cut into blocks: cubes of B × B × B cubes (B = block_cubes, a
// power of two), aligned to the piece, and, where a block fails, its eight halves, down to
// 2 × 2 × 2. A block is merged when the marching-cubes surface inside it
//  * is made only of cube configurations one plane can produce (the paper's types 0, 1 and 2,
//    core/type_merging_tables.h) — a cheap first test;
//  * is one disk: Euler characteristic 1 and one boundary loop, the loop being the block's
//    triangle edges that lie on the block's faces;
//  * faces one way: every triangle's normal has a positive component along the disk's mean
//    normal n (the sum of its area vectors), and the loop projected along n is a simple
//    polygon, so the projection along n is one-to-one on the disk;
//  * is flat: every vertex lies in a slab n·p ∈ [t, t + epsilon_voxels] (index space).
// The disk is then replaced by a triangulation of its loop alone (its inner vertices go),
// made in the projection by clipping ears, best smallest angle first, never with an edge
// between two loop vertices on one block face.
//
// Guarantees (argued in index space; the tests check them in the float32 patient
// coordinates the files are written in, with CGAL's exact predicates):
//  * Closed, manifold, oriented, same Euler characteristic and components as marching cubes:
//    a disk is replaced by a disk with the same boundary, wound like it (the loop is CCW
//    about n). An inner edge joins two loop vertices on no common block face, and an edge
//    outside the block lies in a cube outside it, whose corners on the block lie on one
//    face; so no new edge exists elsewhere.
//  * Within epsilon: both the old disk and its triangulation lie in the slab and project
//    one-to-one onto the same polygon, so every point of either is within epsilon_voxels of
//    the other along n (a bound on the whole surfaces, not only at vertices).
//  * No crossings: marching cubes' triangles cannot cross (each lies in its own cube, and
//    within a cube the case table's do not). A new triangle lies in its block's box, a convex
//    set holding no other triangle; its vertices are on the box's faces but never all on one,
//    so only its loop edges reach the box's surface, and there it meets the surface outside
//    only along those same loop edges (the marching-cubes polylines on the faces, shared by
//    the cubes on both sides). Within a block, the triangles of a planar triangulation of the
//    projection cannot cross. Boxes of different blocks meet only on faces.
//  * Boundaries are kept: a vertex on a mesh border or a piece seam lies on a block face, so
//    it is a loop vertex and stays.
//
// Streaming and memory: pieces of slab_layers cube layers (a multiple of block_cubes) are
// extracted alone with their cube records, merged block by block, compacted and appended, as
// before. Peak ≈ the output mesh + one piece's marching-cubes mesh and cube records (about
// 60 bytes per MC triangle of the piece) + 31 bytes × the padded slice area per thread (the
// extractor's buffers) + 8 bytes per vertex of the piece (the merge's stamps): flat in the
// number of slices. Pieces are made on `threads` threads and appended in order; the output is
// the same for every thread count (it depends on slab_layers and block_cubes: blocks do not
// cross seams).
#pragma once

#include <array>
#include <cstddef>

#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/volume.h"

namespace typemerge::core {

struct FusedMergeOptions {
  // The slab a merged disk must lie in (index space; voxels, so 1.5 mm along z for 3 mm
  // slices): the Hausdorff distance between the merged and the marching-cubes surface is at
  // most this.
  double epsilon_voxels = 0.5;
  // Largest block edge in cubes (a power of two >= 2).
  unsigned block_cubes = 8;
  // Cube layers per piece (a multiple of block_cubes; 0 = one piece).
  unsigned slab_layers = 32;
  // Pieces made at once; 0 = hardware concurrency.
  unsigned threads = 1;
};

struct FusedMergeStats {
  std::size_t triangles_before = 0;  // marching cubes' triangles and vertices
  std::size_t vertices_before = 0;
  std::size_t triangles_after = 0;
  std::size_t vertices_after = 0;
  // Blocks merged, by edge: 2, 4, 8, 16, 32, 64 cubes.
  std::array<std::size_t, 6> blocks_merged{};
  // Blocks not merged (each block tried counts once), by the first test that failed.
  std::size_t rejected_configuration = 0;  // a cube no plane produces
  std::size_t rejected_topology = 0;       // not one disk with one loop
  std::size_t rejected_facing = 0;         // a triangle faces away from the mean normal
  std::size_t rejected_flatness = 0;       // thicker than epsilon
  std::size_t rejected_outline = 0;        // the projected loop is not simple
  std::size_t rejected_separation = 0;     // no plane parts it from another component
  // Merged blocks whose loop could not be triangulated (no valid ear left) or not with fewer
  // triangles than marching cubes: their cubes keep marching cubes' triangles.
  std::size_t blocks_demoted = 0;
  // Loop vertices inside faces two merged blocks share that were thinned away, those given
  // back because a block could not be triangulated without them, and the passes that took.
  std::size_t face_vertices_removed = 0;
  std::size_t face_vertices_restored = 0;
  std::size_t triangulation_passes = 0;

  FusedMergeStats& operator+=(const FusedMergeStats& part);
};

// Extracts the iso-surface of `volume` (as extract_isosurface) merged as described above.
// `extract.cubes` is ignored; `extract.stats` receives the ambiguity counts. Runs on the
// larger of options.threads and extract.threads; the output does not depend on it.
// Preconditions: block_cubes a power of two >= 2; slab_layers a multiple of it.
TriangleMesh extract_fused_merged(const Volume& volume, float iso,
                                  const ExtractOptions& extract = {},
                                  const FusedMergeOptions& options = {},
                                  FusedMergeStats* stats = nullptr);

}  // namespace typemerge::core
