// Validity of a surface for printing, and the repairs that are cheap and safe.
//
// check_validity wraps core::check_mesh (the project's oracle) and names what is wrong; every
// step of this module returns one for its output, so a pipeline can check after each step.
// repair_mesh only does what cannot change the shape: it drops triangles with a repeated
// index, merges the two ends of zero-length edges of zero-area triangles (an exact collapse:
// no vertex moves) and removes vertices no triangle uses. Needle triangles (zero area,
// three distinct positions) would need a vertex to move or an edge flip; they are counted
// and left.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/mesh_checks.h"

namespace typemerge::mesh {

struct Validity {
  core::MeshCheck check;

  bool closed() const { return check.boundary_edges == 0; }
  bool manifold() const {
    return check.non_manifold_edges == 0 && check.non_manifold_vertices == 0;
  }
  bool oriented() const { return check.inconsistent_edges == 0; }
  bool non_degenerate() const { return check.degenerate_triangles == 0; }
  // Closed, manifold, consistently oriented, without degenerate triangles: printable.
  bool valid() const { return check.closed_manifold(); }

  // One line per violated property, e.g. "3 boundary edges (not closed)"; empty when valid.
  std::vector<std::string> problems() const;
};

// `threads` as for core::check_mesh (the result does not depend on it).
Validity check_validity(const core::TriangleMesh& mesh, unsigned threads = 1);

struct RepairReport {
  std::size_t removed_repeated_index_triangles = 0;  // present in the input
  std::size_t collapsed_zero_length_edges = 0;       // vertex merges
  std::size_t removed_collapsed_triangles = 0;       // triangles the merges made degenerate
  std::size_t removed_unreferenced_vertices = 0;
  std::size_t remaining_degenerate_triangles = 0;  // needles: zero area, distinct positions
  Validity validity;                               // of the repaired mesh
};

// Repairs `mesh` in place as described at the top of this file. Vertex order is kept
// (minus the removed vertices); triangle order is kept (minus the removed triangles).
// Precondition: every index < mesh.positions.size().
RepairReport repair_mesh(core::TriangleMesh& mesh);

// core::remove_unreferenced_vertices (core/mesh.h), where the core's reduction uses it too.
using core::remove_unreferenced_vertices;

}  // namespace typemerge::mesh
