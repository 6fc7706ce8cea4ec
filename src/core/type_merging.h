// Type merging, fused into the scan: marching cubes and the merge of flat patches in one pass
// over the lattice, in windows of a few cube layers (the paper's streaming: Oh & Park 1996,
// "A type-merging algorithm for extracting an isosurface from volumetric data", §4), the
// merged triangles emitted directly. The paper merges runs of cubes of one type along scan
// directions by moving vertices; this merges whole flat disks in boxes of cubes and
// re-triangulates each from its border, which reduces more, makes no more caps or needles
// than marching cubes (step 3) and cannot make crossing triangles. Current reductions and
// their history: docs/benchmarks.md.
//
// What it does, per piece of slab_layers cube layers (merge/piece_merge.h), in three passes:
//  1. The box hierarchy (merge/blocks.h). Blocks of B × B × B cubes (B = block_cubes, aligned
//     to the piece; cut by the piece's and the lattice's ends; B/2 along an axis whose step
//     is at least √2 times the finest, so 8 × 8 × 4 on 3 mm slices over 1 mm pixels) are
//     tested bottom up: each 2 × 2 × 2 block (or, if it fails, each of its two layers
//     2 × 2 × 1, or each of their rows 2 × 1 × 1, or each of their cubes alone, which is
//     re-triangulated for shape, not reduced), then every block whose parts all passed, which
//     then replaces them if it passes too. A block's parts halve it along the axes it is
//     longest along in millimetres (within √2 of the longest), so blocks grow towards cubes in
//     millimetres, not in voxels (on a 1.07 × 1.07 × 3 mm grid 2 × 2 × 2 → 4 × 4 × 2 → 8 × 8 × 4
//     cubes); on isotropic grids that is plain octree halving. The marching-cubes triangles of
//     a box split into components (through shared vertices); a component passes the disk test
//     (merge/disk_test.h) when it
//      * is one disk: Euler characteristic 1 and one boundary loop, the loop being its edges
//        that lie on the box's faces (every other edge has a triangle on each side);
//      * faces one way: every triangle's normal has a positive component along the disk's
//        mean normal n (the sum of its area vectors), and the loop projected along n is a
//        simple polygon, so the projection is one-to-one on the disk;
//      * is flat: its vertices lie in a slab n·p ∈ [t, t + w] with w <= epsilon_voxels (index
//        space);
//      * is separated from every other component of the box by its slab (all their vertices
//        on one side of it).
//     Components that fail keep their marching-cubes triangles. A block of 4 or more cubes is
//     tested from its halves' disks instead of their triangles: each is a closed disk bounded
//     by its loop, so the block's surface is a complex of loop vertices, loop edges and disks
//     whose Euler characteristic is V − E + F over those, its loop is the halves' loop edges on
//     the block's faces, and facing and flatness read the halves' stored area vectors and
//     vertices (the same tests, without a second pass over the triangles' topology).
//  2. Loop thinning (merge/loop_thinning.h). A loop vertex inside a face that the boxes of
//     exactly two passing disks share (on no edge of either box) is thinned away where both
//     loops can do without it: Douglas–Peucker on the face's polyline, within
//     sqrt(epsilon² − max(w₁, w₂)²), never shortcutting along a lattice line (a box edge,
//     shared by other boxes). Both disks drop the same vertices.
//  3. Triangulation (merge/disk_triangulation.h, merge/loop_triangulation.h). Each disk's loop
//     is triangulated in the projection by clipping ears, best smallest angle first, never
//     with an edge between two loop vertices on one face of its box, then Lawson flips for
//     shape. A disk that cannot be (or not with at most as many triangles, or not with at most
//     as many caps — an angle above 170° — and as many needles — below 1° — in millimetres as
//     its marching-cubes triangles) gets its thinned vertices back, its neighbours are
//     triangulated again, and with all of them back it falls back to the disks it was
//     composed of in step 1 (each then triangulated the same way), or, made of none, keeps
//     its marching-cubes triangles; this ends because vertices only come back and disks only
//     split. So every disk makes no more caps or needles than marching cubes would there.
//
// Guarantees (argued in index space; the tests check them in the float32 patient coordinates
// the files are written in, with CGAL's exact predicates, on synthetic and real CT):
//  * Closed, manifold, oriented, with marching cubes' Euler characteristic and components: a
//    disk is replaced by a disk with the same border, wound like it (the loop is
//    counter-clockwise about n). A new inner edge joins two loop vertices on no common face of
//    the box; an edge outside the box lies in a cube outside it, whose corners on the box lie
//    on one face: so no edge is made twice. A thinned face edge joins two vertices of the
//    face not on one lattice line: only the two disks' cubes touch it.
//  * Within epsilon over the whole surfaces, not only at vertices: the old disk and its
//    triangulation lie in the slab and project one-to-one onto the same polygon, so every
//    point of either lies within w of the other along n; thinning replaces a polyline in the
//    face by a chord within δ = sqrt(epsilon² − w²) of it both ways (the polyline joins the
//    chord's ends in the plane of the face), so a point over the sliver between them lies
//    within δ across n, in any projection, and within w along n of the other disk:
//    sqrt(δ² + w²) = epsilon. Every output vertex is a marching-cubes vertex, unmoved.
//  * No crossings: marching cubes' triangles cannot cross (each lies in its own cube, and
//    within a cube the case table's do not). A new triangle lies in its box (convex), which
//    holds no other triangles but those of components its slab separates from it; its
//    vertices are on the box's faces but never all on one, so only its loop edges reach the
//    box's surface, where the surface outside meets it along those same edges (the polylines
//    on the faces, shared by the boxes or cubes on both sides). Within a disk, the triangles
//    of a planar triangulation of its projection cannot cross. Boxes meet only on faces.
//  * Borders are kept: a vertex on the mesh border (close_borders off) or a piece seam lies
//    on box faces that no second disk shares, so it stays, as does every border edge.
//
// Streaming and memory: each piece is extracted alone with its cube records (marching cubes'
// slabs), without vertex normals, merged (its blocks tested layer by layer of blocks as
// marching cubes makes them, passes 2 and 3 after), compacted and appended; normals are computed for
// the vertices kept only, equal to marching cubes' (none with extract.vertex_normals false).
// Peak ≈ the output mesh + per piece being made: its marching-cubes mesh and cube records
// (about 50 bytes per MC triangle: positions and lattice edges 20 bytes per vertex, triangles
// 12, cube records 20 per cube) + the merge's state (18 bytes per vertex; per merged MC
// triangle its id and float area vector, 16 bytes; 4 bytes per merged vertex; the disks'
// loops, and a 44-byte record per part for step 3's fallback, its loop rebuilt only if it is
// needed; the block being tested, ~40 bytes per corner of its triangles) + 31 bytes (22 for
// int16 samples) × the padded slice area (the extractor's buffers) — flat in the number of
// slices; with T threads up to T + 1 pieces exist. Each thread keeps these arrays from piece
// to piece (sized for the largest piece's estimate; a thread's last piece frees the slice
// buffers and the merge's per-vertex arrays early) and the arrays of pieces already appended
// are written again, so pages are mapped once per thread, not once per piece
// (merge/piece_merge.h, PieceScratch).
// The output is the same for every thread count; it depends on slab_layers, block_cubes,
// blocks_follow_spacing and the grid's spacing (no box crosses a seam: seams cost some
// reduction).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/volume.h"

namespace typemerge::core {

struct MergeOptions {
  // The slab a merged disk must lie in (index space; voxels, so 1.5 mm along z for 3 mm
  // slices): the Hausdorff distance between the merged and the marching-cubes surface is at
  // most this.
  double epsilon_voxels = 0.5;
  // When > 0: the bound in millimetres of patient space instead (epsilon_voxels is then
  // ignored): the two-sided Hausdorff distance between the merged and the marching-cubes
  // surface, over the whole surfaces, is at most this (merge/tolerance.h).
  double epsilon_mm = 0.0;
  // Largest block edge in cubes (a power of two >= 2, at most 32). Larger blocks rarely pass
  // on CT within half a voxel (few 16-blocks are that flat) and cost a test each; larger
  // bounds let larger blocks pass.
  unsigned block_cubes = 8;
  // Blocks shaped by the grid's spacing (step 1 above); false: cubes of block_cubes halved
  // along every axis at once, whatever the spacing.
  bool blocks_follow_spacing = true;
  // Cube layers per piece on average (0 = one piece): about layers / slab_layers pieces (an
  // even number where more than one), cut where the estimated surface below is equal
  // (detail::piece_bounds); blocks are aligned to the piece.
  unsigned slab_layers = 32;
  // Pieces made at once; 0 = hardware concurrency.
  unsigned threads = 1;
  // When set, called with slice ranges [begin, end) that the extraction reads no more: the
  // ranges are disjoint and not empty, they cover the volume's slices [0, nz), and each is
  // reported as soon as every piece that reads it has read it (a piece's own slices as its
  // marching cubes passes them, two or more at a time; the slices two pieces share once both
  // have).
  // Calls may come from several threads at once. A holder that needs the volume no more can
  // release them (Volume::release_slices) so that the volume's memory shrinks while the
  // surface is made. The output does not depend on it.
  std::function<void(std::int64_t begin, std::int64_t end)> slices_done = nullptr;
  // Memory before speed: a thread's marching-cubes slice buffers (two slices' edge tables,
  // 6 MB for 512 × 512 slices) give their pages back while its piece merges, and fault them
  // in again for its next piece (about 1 % of an extraction's time). The output does not
  // depend on it.
  bool return_idle_pages = false;
};

struct MergeStats {
  std::size_t triangles_before = 0;  // marching cubes' triangles and vertices
  std::size_t vertices_before = 0;
  std::size_t triangles_after = 0;
  std::size_t vertices_after = 0;
  // Disks merged, by their box's edge: 1 (layers and rows of a 2-block), 2, 4, 8, 16, 32.
  std::array<std::size_t, 6> blocks_merged{};
  // Components not merged (each one tried counts once), by the test that failed.
  std::size_t rejected_topology = 0;       // not one disk with one loop
  std::size_t rejected_facing = 0;         // a triangle faces away from the mean normal
  std::size_t rejected_flatness = 0;       // thicker than epsilon
  std::size_t rejected_outline = 0;        // the projected loop is not simple
  std::size_t rejected_separation = 0;     // no plane parts it from another component
  // Merged blocks whose loop could not be triangulated (no valid ear left) or not with fewer
  // triangles than marching cubes: their cubes keep marching cubes' triangles.
  std::size_t blocks_demoted = 0;
  // Merged blocks whose whole loop could not be triangulated well, replaced by the blocks
  // they were composed of.
  std::size_t blocks_split = 0;
  // Loop vertices inside faces two merged blocks share that were thinned away, those given
  // back because a block could not be triangulated without them, and the passes that took.
  std::size_t face_vertices_removed = 0;
  std::size_t face_vertices_restored = 0;
  std::size_t triangulation_passes = 0;
  // The work of step 1's tests, and the part of it spent on boxes that failed (what a test
  // rejecting boxes before their components are built could save at most): marching-cubes
  // triangles read by box tests (test_triangles), and parts' loop vertices read by tests of
  // composed blocks (test_parts).
  std::size_t tested_triangles = 0;
  std::size_t tested_triangles_failed = 0;
  std::size_t tested_loop_vertices = 0;
  std::size_t tested_loop_vertices_failed = 0;

  MergeStats& operator+=(const MergeStats& part);
};

// Extracts the iso-surface of `volume` (as extract_isosurface) merged as described above.
// `extract.cubes` is ignored; `extract.stats` receives the ambiguity counts. Runs on the
// larger of options.threads and extract.threads; the output does not depend on it.
// Throws std::invalid_argument unless block_cubes is a power of two >= 2, epsilon_voxels
// >= 0, epsilon_mm finite and >= 0, and extract.mode is consistent (classic mode's holes are not loops on box faces).
TriangleMesh extract_type_merged(const Volume& volume, float iso,
                                  const ExtractOptions& extract = {},
                                  const MergeOptions& options = {},
                                  MergeStats* stats = nullptr);

namespace detail {

// The pieces' cube layers: [bounds[k], bounds[k + 1]) for k < bounds.size() − 1, from 0 to
// `layers` (empty when layers is 0), about layers / slab_layers of them (rounded up to an even
// count when above 1 and the layers allow it: two threads share them evenly), cut where the
// surface estimated from the volume's samples is equal (so pieces cost about the same: the cut
// x-, y- and z-edges in every 8th row, the caps of a body cut by the volume's ends included),
// on the multiple of the blocks' z edge (step 1: block_cubes, or half of it on thick slices)
// nearest in that estimate where pieces are at least two blocks high. `threads` only speeds
// up the estimate: the bounds do not depend on it. With `vertices`, it receives per piece
// that estimate scaled to all rows: about marching cubes' vertices in the piece (left empty
// when there is one piece and nothing was estimated).
std::vector<std::int64_t> piece_bounds(const Volume& volume, float iso,
                                       const ExtractOptions& extract, const MergeOptions& options,
                                       std::int64_t layers, unsigned threads,
                                       std::vector<double>* vertices = nullptr);

}  // namespace detail

}  // namespace typemerge::core
