// check_mesh: exact combinatorial and geometric invariants of a TriangleMesh — the oracle the
// extraction and merging tests are written against, so it is kept simple enough to trust.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "core/mesh.h"

namespace typemerge::core {

struct MeshCheck {
  std::size_t vertices = 0;   // vertices used by at least one valid triangle
  std::size_t edges = 0;      // undirected edges of valid triangles
  std::size_t triangles = 0;  // valid triangles (three distinct indices)

  std::size_t boundary_edges = 0;         // used by exactly one triangle
  std::size_t non_manifold_edges = 0;     // used by more than two triangles
  std::size_t inconsistent_edges = 0;     // some direction of the edge used by two triangles
  std::size_t non_manifold_vertices = 0;  // triangles around the vertex are not one disk or fan
  std::size_t degenerate_triangles = 0;   // repeated index, or zero area
  std::size_t components = 0;             // connected through shared vertices

  std::int64_t euler_characteristic = 0;  // vertices − edges + triangles
  double volume = 0.0;  // signed enclosed volume (divergence theorem); > 0 when wound outward
  double area = 0.0;

  // Every edge in exactly two triangles with opposite directions, manifold vertices, no
  // degenerate triangle.
  bool closed_manifold() const {
    return boundary_edges == 0 && non_manifold_edges == 0 && inconsistent_edges == 0 &&
           non_manifold_vertices == 0 && degenerate_triangles == 0;
  }
};

// Checks `mesh`. A triangle with a repeated index counts as degenerate and is left out of
// everything else; a triangle with distinct indices but zero area (the cross product of its
// edge vectors, computed in double, is exactly zero) counts as degenerate but still takes
// part in the topology, which it does not disturb.
// `threads` (0: hardware concurrency) share the per-vertex work; the result is the same for
// any count (area and volume are summed in fixed chunks, in order). Throws std::length_error
// above 1.4 billion triangles (corners are numbered in 32 bits).
// Precondition: every index < mesh.positions.size().
MeshCheck check_mesh(const TriangleMesh& mesh, unsigned threads = 1);

// check_mesh of `mesh` when it is a mesh that check_mesh found closed and manifold (`before`)
// with `removed_components` whole components taken out and no vertex left unused: every
// edge and vertex link lies in one component, so what is left is closed and manifold too and
// its topology follows from the counts (edges = 3 T / 2); only area and volume are summed
// again, in check_mesh's order, so the result equals check_mesh's exactly. The finishing
// steps remove components after an extraction that was just checked: this spares a second
// full check, a noticeable share of a one-thread conversion (docs/benchmarks.md, "Moved from
// headers and the README"). Precondition: before.closed_manifold().
MeshCheck check_after_removing_components(const TriangleMesh& mesh, const MeshCheck& before,
                                          std::size_t removed_components, unsigned threads = 1);

// Triangles with an angle above 170° (caps) and with an angle below 1° (needles), the
// shapes slicers and FE tools dislike, in the mesh's own coordinates (judge shapes in
// millimetres: to_patient first). A triangle with a zero-length edge counts as a needle.
struct ExtremeAngles {
  std::size_t above_170 = 0;
  std::size_t below_1 = 0;

  ExtremeAngles& operator+=(const ExtremeAngles& other) {
    above_170 += other.above_170;
    below_1 += other.below_1;
    return *this;
  }
};
ExtremeAngles count_extreme_angles(const TriangleMesh& mesh);
// The same for one triangle (each count 0 or 1), on double positions.
ExtremeAngles extreme_angles_of(const std::array<double, 3>& p, const std::array<double, 3>& q,
                                const std::array<double, 3>& r);

namespace detail {
// The same result by the simplest means (a global sort, a vector per vertex): the oracle of
// the tests.
MeshCheck check_mesh_by_sorting(const TriangleMesh& mesh);
}  // namespace detail

}  // namespace typemerge::core
