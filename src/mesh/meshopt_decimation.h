// decimate_with_meshopt: bounded decimation with meshoptimizer's simplifier
// (meshopt_simplify, Debian's libmeshoptimizer-dev 0.18), checked after, because its bound
// and its topology rules are weaker than what a printable surface needs.
//
// The simplifier (A. Kapoulkine, meshoptimizer src/simplifier.cpp) ranks edge collapses by
// Garland & Heckbert 1997 quadrics and runs them in passes of independent collapses, each
// onto an existing vertex (so every vertex of the result is a vertex of the input), refusing
// collapses that flip a triangle. What it does not guarantee, and what is checked here:
//  * the bound: its `target_error` is relative to the mesh's extent (meshopt_simplifyScale)
//    and is the root of an area-weighted mean of squared distances to the collapsed planes,
//    not the largest distance; so it is given kErrorFactor * max_error and the result's
//    distance to the input is measured (check 3);
//  * topology: there is no link-condition test, so a collapse across a thin handle can leave
//    a non-manifold edge or vertex, change the Euler characteristic or split a component;
//  * crossings: only local flips are refused; triangles far apart along the surface can be
//    made to cross.
// Where a pass's result fails a check (a bad triangle, a far point), the next pass keeps the
// input's triangles within a few input edges of it as they are (their border locked with
// meshopt_SimplifyLockBorder, so kept and simplified triangles still meet edge for edge) and
// simplifies the rest again, at most kMaxMeshoptPasses times. A result that still fails, or
// that kept everything, is refused: `mesh` is left as it was and `fallback` says why, so
// decimate_mesh (mesh/decimation.h) can run OpenMesh on it.
//
// The checks, cheapest first:
//  1. the input is closed manifold (else refused at once: OpenMesh splits what it can);
//  2. the result's triangles on an edge not used exactly twice in opposite directions, around
//     a vertex that is not one fan, or of zero area; at the end core::check_mesh of the
//     result: closed manifold, the input's Euler characteristic and component count;
//  3. the two-sided sampled distance (core/mesh_distance.h): every input vertex to the
//     result (OpenMesh's bound, so the two libraries promise the same there) and points of the
//     result's surface, surface_samples at the input's mean edge length, to the input; the
//     largest must be <= max_error (else the next pass). Sampling the result at the input's
//     resolution costs about as much as the vertex direction; sampling the input's triangles
//     too, or denser, would cost more than the simplifier. Skipped for an infinite max_error;
//  4. crossing pairs of the result (core::find_self_intersections, about linear in its
//     triangles, and the result is the smaller mesh): refused when it has more than the input
//     (which is only counted when the result has any, since marching-cubes surfaces have
//     none). Always on, not only with --check-intersections: a crossing makes the print fail,
//     and on the reduced mesh the count costs a small part of the simplification.
// Figures (abdomen bone, mc, and skin): docs/benchmarks.md ("Moved from headers and the
// README"), printed by tests/mesh/mesh_bench.cpp --stl.
#pragma once

#include "core/mesh.h"
#include "mesh/decimation.h"

namespace typemerge::mesh {

// Most meshopt_simplify passes (the first and three that keep the problems of the last).
inline constexpr int kMaxMeshoptPasses = 4;
// meshopt's target error is max_error times this: its error is a mean, so a target of
// max_error itself leaves many sampled points farther than max_error; a quarter of it leaves
// far fewer for the repair passes (the counts are among the figures above).
inline constexpr double kErrorFactor = 0.25;

// Decimates `mesh` in place with meshoptimizer when every check above passes (report.fallback
// empty, report.decimator == meshopt); otherwise `mesh` is unchanged and report.fallback names
// the first failed check. Vertex normals of an accepted result are recomputed (area-weighted).
// options.max_normal_deviation is not used. Preconditions: as decimate_mesh; options.max_error
// finite or options.target_triangles > 0.
DecimationReport decimate_with_meshopt(core::TriangleMesh& mesh,
                                       const DecimationOptions& options = {});

}  // namespace typemerge::mesh
