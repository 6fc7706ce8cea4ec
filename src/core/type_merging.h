// Type merging (Oh & Park 1996, "A type-merging algorithm for extracting an isosurface from
// volumetric data", The Visual Computer 12:406–419), as specified in type-merging-spec.md:
// §1.5 scan order, §2.3 moving table, §3 / Appendix A type table (tables in
// type_merging_tables.h), §4.1–4.2 the merge procedure with FLAG consistency, §4.4 decisions
// D1–D11, §4.5 the checked variant, and type 3 (§3.4, D10) last.
//
// What it does: the marching-cubes mesh is reduced by merging runs of cubes with the same
// index along a direction of the type table. Each merge of C with C + d moves the surface
// vertices on the rear edges of C + d onto its front edges (moving table row d), which is done
// as half-edge collapses on the indexed mesh. Unlike the paper, every collapse is checked
// (§4.5): link condition (manifold and topology preserved), no fold-over (a moved triangle
// turns by at most max_normal_change_deg, and its normal stays within
// max_normal_to_gradient_deg of the mean MC vertex normal, i.e. of −∇f), and every original
// MC vertex absorbed by an affected vertex stays within epsilon_voxels of the new mesh. Runs
// are capped at run_cap cubes. Type 3 then removes, with the same checks, the vertex at the
// centre of each 2×2 block of cubes that one plane makes with corner cubes on a diagonal
// (type3_blocks in type_merging_tables.h: the paper's four slice groups, their mirror images
// and the same blocks in the xz and yz planes) and the vertices next to it on the block's
// internal edges, as spec §3.4 suggests. Surviving vertices keep their MC position and normal, so
// every output vertex lies exactly on the MC surface. Zero-area slivers left by collinear
// vertices (frequent on flat data) are removed by exact collapses afterwards (D6).
//
// Guarantees (for a closed, manifold MC mesh, i.e. consistent mode): the output is closed,
// edge- and vertex-manifold, consistently oriented, with the same Euler characteristic and
// number of components as the MC mesh. Vertices on a mesh boundary (close_borders off,
// classic mode's holes, a piece's seams) never move and never absorb another vertex, so
// boundaries are kept exactly.
//
// No crossings (the crossing guard, MergeOptions::prevent_crossings): the local checks above
// cannot see a second sheet of surface a voxel away (two cortices, cortex and marrow wall), so
// a stretched fan can reach through it: 8 crossing pairs on the abdomen CT's bone. The
// argument: marching cubes' triangles cannot cross (each lies in its own cube, and within a
// cube the case table's triangles do not cross), and a vertex that is frozen (neither moves
// nor absorbs another) keeps its MC triangles' corners. So after merging, the triangles that
// are not MC triangles as they were are tested exactly against every triangle whose box they
// meet (core/self_intersections.h; on the float positions the output will be written with,
// patient mm for extract_type_merged, so the guarantee holds in millimetres whatever the
// spacing); the input vertices of every class at a corner of a crossing pair are frozen, and
// the piece is merged again from its MC surface. Each round freezes at least the two members
// of some merged class (a crossing pair has a changed triangle, so a corner whose class has
// more than one member, none of them frozen), so the rounds end; at the worst every vertex
// near a crossing is frozen and the surface there is marching cubes'. The output then has no
// crossing pair but those marching cubes' own floats would have (none in any test; counted in
// MergeStats::crossings_left). Pieces cannot cross each other: a piece's triangles lie in its
// layers and meet the next piece's only at seam vertices and seam edges, which merging never
// moves. Cost: the exact test of the changed triangles each round, and a second merge of each
// piece where a pair crossed (abdomen, 1 thread: 300 HU 726 → 1,539 ms, one piece of five
// merged twice; −500 HU 2,564 → 3,102 ms, none); memory: the search's grid, about 100 bytes a
// triangle of one piece, held after the merge state is freed (README, "The crossing guard").
//
// Memory of merge_types (the whole-mesh approach of §4.5, "polygonize, merge, compact"):
// peak ≈ the MC mesh (24 bytes per vertex, 12 per triangle) + 20 bytes per boundary cube
// (lattice records from the extractor) + 32 bytes per vertex (union-find parent, class ring,
// fan ring, class size, CSR offset and live end, distance witness and its version) + 28
// bytes per triangle (CSR incidence, current corners, shape version and alive bit) + 1 byte per
// triangle (fan slot) + 3 bytes per boundary cube (FLAG, run length, started) + 4 bytes per
// cube row (y, z) + the compacted output — about 80 bytes per MC triangle (abdomen bone: 843,594
// triangles, 422,065 vertices, 411,058 cubes). No
// per-vertex heap allocation, no hash map: everything is a flat array indexed by vertex,
// triangle or cube record.
//
// Streaming (extract_type_merged, spec §4.5's slabs): the lattice is cut into pieces of
// MergeOptions::slab_layers cube layers. Each piece is extracted alone (marching cubes with
// its cube records), merged alone in the paper's scan order, compacted and appended to the
// output; its seams (the vertices of its first and last slice) lie on its boundary, so no
// merge moves them or moves a vertex onto them, and the pieces join exactly where
// extract_isosurface's slabs join. With one thread one piece exists at a time, so
// peak ≈ the output mesh + 80 bytes per MC triangle of one piece + 31 bytes × the padded
// slice area (the extractor's slice buffers) — bounded by a few dozen slices whatever the
// number of slices (abdomen CT, slices repeated up to N = 1072: README); with T threads up to
// T + 1 pieces exist (T being made, one waiting for its predecessor to be appended). The
// output is the same for every thread count; it depends on slab_layers (runs stop at seams).
//
// Parallelism: pieces are independent, so `threads` of them are made at once, each appended
// as soon as the pieces before it are (a slow piece holds up the appending, not the other
// threads: abdomen, 2 threads, 8–14 % faster than making them in waves). merge_types, on a
// whole mesh, is one serial pass in scan order.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/type_merging_tables.h"
#include "core/volume.h"

namespace typemerge::core {

struct MergeOptions {
  // D7: every original MC vertex stays within this distance (voxels) of the merged mesh.
  double epsilon_voxels = 0.5;
  // D9: most cubes in one merged run (2 = pairs only). Bounds needle triangles: the spec's
  // prototype loses 0.3–3 points of reduction on curved surfaces with a cap of 4.
  int run_cap = 6;
  // Most MC vertices one output vertex may absorb (its class; 0 = no limit). A collapse that
  // would make a larger class is rejected. Bounds the cost of a collapse, which tests every
  // absorbed vertex against the new fan (D7): on the flat caps close_borders puts where a CT
  // body meets the volume border, classes otherwise grow to over 1,500 vertices. Costs little
  // reduction: abdomen CT skin +1.3 % triangles, bone +0.004 %.
  std::uint32_t max_class_vertices = 64;
  // D10: type-3 blocks (spec §3.4), after types 0–2. They reduce what types 0–2 cannot
  // (generic plane (1,2,3): 100 % → 44 % of MC) and cost some time; abdomen CT, 1 thread
  // (`extract_bench --algorithms mc,tm012,tm`): bone 300 HU 68.4 % → 57.9 % of MC
  // triangles, skin −500 HU 39.9 % → 30.8 %, Hausdorff still 0.5 voxel; 372 → 468 ms and
  // 1.49 → 1.79 s.
  bool type3 = true;
  // D4: hexagons merge along the paper's two lines with an x component; true adds the third.
  bool hexagon_all_lines = false;
  // §4.5 fold-over tests.
  double max_normal_change_deg = 45.0;
  double max_normal_to_gradient_deg = 80.0;
  // D6: collapse zero-area slivers after merging.
  bool remove_slivers = true;
  // extract_type_merged: pieces of this many cube layers (z) are extracted and merged alone,
  // their seams fixed (see Streaming above); 0 = one piece, the whole surface in the paper's
  // scan order. Seams cost some reduction and smaller pieces less memory and time; abdomen CT
  // (134 slices), 1 thread, tm/mc triangles and time (`extract_bench --algorithms mc,tm
  // --slab-layers L`, one run): bone 300 HU: 16 → 58.9 %, 438 ms; 32 → 57.9 %, 471 ms;
  // 64 → 57.6 %, 546 ms; one piece 57.1 %, 509 ms. −500 HU: 16 → 32.7 %, 1.48 s; 32 →
  // 30.8 %, 1.77 s; 64 → 29.6 %, 2.15 s; one piece 28.4 %, 2.41 s. (merge_types ignores it.)
  unsigned slab_layers = 32;
  // extract_type_merged: pieces made at once; 0 = hardware concurrency. (merge_types is
  // serial.)
  unsigned threads = 1;
  // The crossing guard (see "No crossings" above): no two output triangles cross.
  bool prevent_crossings = true;
};

struct MergeStats {
  // Merges (C absorbed C + d) by paper type 0, 1, 2; of the type-2 merges, those of hexagons
  // and of minor cubes; by direction (MergeDirection order).
  std::array<std::size_t, 3> cubes_merged_by_type{};
  std::size_t hexagon_merges = 0;
  std::size_t minor_merges = 0;
  std::array<std::size_t, kMergeDirectionCount> merges_by_direction{};
  std::size_t type3_groups = 0;  // type-3 blocks whose centre vertex was removed
  std::size_t runs_capped = 0;  // a merge was possible but the run had run_cap cubes
  std::size_t merges_abandoned = 0;  // some collapse was rejected: the merge was undone
  std::size_t rejected_sliver = 0;   // of those: a sliver it made could not be removed

  std::size_t collapses_tried = 0;  // vertex moves of merges and of the sliver clean-up
  std::size_t collapses_done = 0;
  std::size_t rejected_boundary = 0;  // the moving or absorbing vertex is on a boundary
  std::size_t rejected_link = 0;      // not an edge, or the link condition fails
  std::size_t rejected_fan_size = 0;  // fan larger than the fixed buffers (kMaxFan)
  std::size_t rejected_normal = 0;    // a triangle would turn by more than the limit
  std::size_t rejected_gradient = 0;  // a triangle would face away from the MC normals
  std::size_t rejected_distance = 0;  // an absorbed MC vertex would be farther than epsilon
  std::size_t rejected_class_size = 0;  // the class would exceed max_class_vertices
  std::size_t rejected_frozen = 0;      // a vertex the crossing guard froze

  // The crossing guard: merges repeated with more vertices frozen, vertices frozen, and
  // crossing pairs left that no merge made (zero unless rounding to patient floats makes one).
  std::size_t crossing_rounds = 0;
  std::size_t vertices_frozen = 0;
  std::size_t crossings_left = 0;

  std::size_t sliver_collapses = 0;
  std::size_t slivers_left = 0;  // slivers no checked collapse could remove

  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  std::size_t vertices_before = 0;
  std::size_t vertices_after = 0;
};

// Merges `mesh` in place, serially in scan order, and compacts it (unused vertices dropped,
// the rest renumbered in their original order, triangles kept in their original order).
// Preconditions: `mesh` and `cubes` come from one extract_isosurface call (cubes = its
// ExtractOptions::cubes output) and have not been modified;
// options.run_cap >= 1; options.epsilon_voxels >= 0.
void merge_types(TriangleMesh& mesh, std::span<const BoundaryCube> cubes,
                 const MergeOptions& options = {}, MergeStats* stats = nullptr);

// extract_isosurface followed by merge_types, streamed in pieces of options.slab_layers cube
// layers (see Streaming above). `extract.cubes` is ignored; `extract.stats` receives the
// ambiguity statistics of the whole surface. Runs on the larger of options.threads and
// extract.threads; the output does not depend on it.
TriangleMesh extract_type_merged(const Volume& volume, float iso,
                                 const ExtractOptions& extract = {},
                                 const MergeOptions& options = {}, MergeStats* stats = nullptr);

namespace detail {

// Squared distance from point p to triangle (a, b, c) (Ericson, Real-Time Collision
// Detection §5.1.5); correct for degenerate triangles too.
double point_triangle_distance_squared(const std::array<double, 3>& p,
                                       const std::array<double, 3>& a,
                                       const std::array<double, 3>& b,
                                       const std::array<double, 3>& c);

}  // namespace detail

}  // namespace typemerge::core
