// Self-intersections of a triangle mesh: pairs of triangles that cross or overlap, decided with
// exact predicates (CGAL's exact-predicates kernel: orientation tests on the float coordinates
// as stored, no rounding). The one place the project decides "do these two triangles cross";
// `typemerge stats --self-intersections`, `convert --check-intersections`, the benchmarks,
// the tests and the fuzzers all use it.
//
// What counts (the semantics of CGAL's Polygon_mesh_processing::self_intersections, so a mesh
// we call clean is clean for CGAL too; a test compares the two):
//  - triangles that share no vertex: any common point;
//  - triangles that share exactly one vertex (by index): the edge opposite it in either one
//    meets the other triangle, i.e. they meet somewhere besides the shared vertex;
//  - triangles that share an edge (two vertices): they overlap, i.e. they are coplanar and lie
//    on the same side of the shared edge (a fold of 0°);
//  - triangles with the same three vertices: always.
// Degenerate triangles (three collinear corners) take no part in the pairs; they are counted
// apart (CGAL reports them as a pair of a face with itself).
//
// Cost: one axis-aligned box per triangle in a sparse uniform grid (cells twice the mean box
// extent, grouped by a radix sort: O(n) for surfaces of even triangle sizes, as the extractors
// make), or
// CGAL's box_intersection_d when the sizes are too uneven for a grid; then the exact test per
// pair of meeting boxes, most of them decided by a statically filtered orientation in double
// before CGAL's predicates. About 1 µs a triangle, half the time of CGAL's box_intersection_d
// with the same pair test (figures: docs/benchmarks.md, "Moved from headers and the README").
// The core links CGAL for this alone (header-only kernel and box intersection, GMP behind the
// filters).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh.h"

namespace typemerge::core {

struct SelfIntersections {
  // Every crossing pair (first < second), sorted; at most `max_pairs` of them when the search
  // was bounded (then `truncated`).
  std::vector<std::array<std::uint32_t, 2>> pairs;
  bool truncated = false;
  std::size_t degenerate_triangles = 0;  // collinear corners: not tested against others
};

// All crossing pairs of `mesh`'s triangles; with max_pairs > 0 the search stops after that
// many (the count then is a lower bound; `truncated` says so). With `only_with` non-empty (one
// flag per triangle), only pairs in which at least one triangle is flagged are looked for:
// for a caller that changed some triangles of a mesh whose others cannot cross (marching
// cubes' own cannot), it flags the changed ones.
SelfIntersections find_self_intersections(const TriangleMesh& mesh, std::size_t max_pairs = 0,
                                          std::span<const std::uint8_t> only_with = {});

// The pair test alone, for triangles s and t of `mesh` (s != t), with the rules above.
bool triangles_intersect(const TriangleMesh& mesh, std::uint32_t s, std::uint32_t t);

namespace detail {
// find_self_intersections with the broad phase chosen: `library` = CGAL's box_intersection_d,
// else the grid (which falls back to the library for uneven triangle sizes). For tests.
SelfIntersections find_self_intersections_by(const TriangleMesh& mesh, std::size_t max_pairs,
                                             std::span<const std::uint8_t> only_with, bool library);
}  // namespace detail

}  // namespace typemerge::core
