// Bounded collapses: fewer triangles on a type-merged surface, every guarantee kept.
//
// The second stage of a reduction (bounded_reduction.h), where merging alone cannot reach a
// count within its bound. Each step is an edge collapse u → v: vertex u disappears, every
// triangle of u not on the edge uv is re-spanned to v, the two on it go. Without placement no
// vertex moves, so every vertex of the result is a vertex of the input. With placement
// (CollapseOptions::move_vertices), v also moves to the point that minimises the quadric of
// the edge (the least-squares point of the input's planes around u and v, regularised towards
// v along directions the planes leave free) when that point lies within half the edge's
// length of v, else to the quadric's minimum on the segment uv (it stays when the move would
// be a hundredth of ε or less); then every triangle of v changes too, and every test below is
// made on all the changed triangles at the moved position. No guarantee rests on vertices
// staying on the reference: each is tested for every new triangle as it is.
//
// A collapse is made only when all of these hold (otherwise the surface is left as it was):
//  - topology: the link condition (the common neighbours of u and v are exactly the two
//    vertices opposite uv) and both of those keep three or more neighbours. A closed, oriented
//    2-manifold stays one, with the same Euler characteristic and components (an open one
//    too, its border kept: see collapse_within_bound);
//  - no crossing: every new triangle is tested with the exact predicates of
//    self_intersections.h against every live triangle whose box its box meets (a dynamic
//    hashed grid) and against the other new triangles; a pair is passed over without it only
//    when the same statically filtered orientation proves the other triangle's own corners
//    strictly on one side of the new triangle's plane (then they cannot count as crossing);
//  - shape: no new triangle has an angle above 170° or below 1° (count_extreme_angles'
//    caps and needles, so their counts never grow), and none turns more than 78° away from
//    the triangle it replaces;
//  - surface → reference within ε: for a new triangle T with corners p_i, max dist(p_i, R) +
//    ρ(T) ≤ ε, ρ(T) the largest distance from a point of T to its nearest corner, proves every
//    point of T within ε of the reference R (the distance to a set is 1-Lipschitz); where it
//    does not, T is halved at its longest side's midpoint (its distance searched) and the
//    halves tried the same way, down to kBisectDepth levels; else dist(c, R) + max |p_i − c|
//    ≤ ε at its centroid c proves it, T split in four where it does not and each part tried
//    by the centroid test, down to kLipschitzDepth levels. A searched point ε or more away
//    refuses the collapse at once, as does failing every test. Before the centroid test, on a
//    closed reference, the overlay proof (exact where it applies, so it proves triangles far
//    larger than ε): the reference triangles within a slab of kOverlaySlab × ε around T's
//    plane, cut to it and projected onto T, cut T into convex pieces; the distance to one
//    triangle is convex, so a piece's corners within ε of its triangle prove the piece. The
//    pieces cover T when the reference crosses neither face of the slab over T and the
//    pieces' signed areas (negative where the reference projects reversed) sum to at least
//    half T's: the projection's degree is then one integer over T, at least 1 (argued at
//    overlay_proves);
//  - reference → surface within ε: every reference triangle is assigned one triangle of the
//    surface that is within ε of its three corners, hence of all of it (the distance to one
//    triangle is a convex function); where none is, its four parts of a midpoint split are
//    assigned instead, down to kPatchDepth levels; on a closed surface, before a reference
//    triangle is split, the overlay proof below with the roles swapped (the surface beneath
//    the reference triangle) may prove it within ε of several surface triangles together,
//    and it is listed with each of them. The parts assigned to the triangles a collapse
//    changes must each find such a triangle (or split into parts that do, or be proved again
//    by the overlay) among those around v afterwards, else the collapse is refused. A part no
//    single triangle covers at the start (nor the overlay) is held: no collapse may change a
//    triangle near it.
// Both distances are computed in double on the float coordinates as stored; the bound holds
// to rounding (far below 1e-6 of the coordinates).
//
// Order: the Garland–Heckbert quadric cost of moving u onto v (the planes of the input's
// triangles around both, area-weighted; at v's placed position with placement), smallest
// first; a candidate u → w refused now is tried again after a collapse onto a neighbour of u
// (which changes u's triangles). With
// local_rms, a candidate whose cost over its planes' summed area exceeds local_rms² (the
// area-weighted root-mean-square distance from v to those planes above local_rms) is passed
// over, and tried again only once a collapse onto u or v changes its cost: the collapses then
// stop where each further one would move the surface locally by more than local_rms on
// average, well before the bound stops them.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "core/mesh.h"
#include "core/volume.h"

namespace typemerge::core {

struct CollapseOptions {
  double bound = 0.0;         // ε, in the meshes' units (> 0)
  std::size_t target = 0;     // stop once at most this many triangles are left; 0: go on
                              // while any collapse is allowed
  double local_rms = 0.0;     // > 0: only candidates within this quadric estimate (Order, above)
  // Placement (above): a collapse u → v may move v to its quadric's point. The moved position
  // is a float point q of `frame` (an index grid), written to the surface as geometry.apply(q)
  // rounded to float, exactly what to_patient makes of q, and q to (*frame)[v]: so the
  // surface to_patient makes from `frame` afterwards is the one checked. Without `geometry`,
  // the surface's own frame (the position rounded to float; `frame` unused).
  bool move_vertices = false;
  const IndexToPatient* geometry = nullptr;
  std::vector<std::array<float, 3>>* frame = nullptr;
};

struct CollapseStats {
  std::size_t collapses = 0;
  std::size_t refused_topology = 0;
  std::size_t refused_shape = 0;
  std::size_t refused_distance = 0;  // either direction
  std::size_t overlay_proofs = 0;    // new triangles proved within ε by the overlay proof
  std::size_t reference_overlay_proofs = 0;  // reference triangles proved so (the swapped one)
  std::size_t refused_crossing = 0;
  std::size_t passed_over_local_error = 0;  // candidates beyond local_rms, never queued
  std::size_t held_reference_triangles = 0;  // a part of each no single triangle covered at first
};

// Collapses `surface` in place (its triangles, and with placement the positions of the
// vertices moved; unused vertices stay: remove_unreferenced_vertices afterwards) until
// `options.target` or until no allowed collapse is left.
// Preconditions, the caller's: `surface` is an oriented 2-manifold without crossing
// triangles, in the same units and frame as `reference`, and every point of each is within
// options.bound of the other. Where it is open (edges in one triangle: a surface left open at
// the volume's border), the vertices of those edges are never collapsed away nor moved, so
// its border stays as it is; the reference must be closed wherever the surface is (as marching
// cubes' and type merging's surfaces of one volume and options are): the overlay proof runs
// only when the surface has no border and counts on the reference having none. Throws
// std::invalid_argument for a bound not finite and > 0, a local_rms not finite and >= 0, or
// placement with a geometry but no frame of one position a vertex.
CollapseStats collapse_within_bound(TriangleMesh& surface, const TriangleMesh& reference,
                                    const CollapseOptions& options);

}  // namespace typemerge::core
