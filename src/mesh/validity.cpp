#include "mesh/validity.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <numeric>
#include <vector>

#include "core/union_find.h"

namespace typemerge::mesh {
namespace {

std::string count_line(std::size_t n, const char* what) {
  return std::to_string(n) + " " + what;
}

bool has_repeated_index(const std::array<std::uint32_t, 3>& t) {
  return t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
}

// Exactly zero cross product in double, the rule core::check_mesh uses.
bool has_zero_area(const core::TriangleMesh& mesh, const std::array<std::uint32_t, 3>& t) {
  const auto& p0 = mesh.positions[t[0]];
  const auto& p1 = mesh.positions[t[1]];
  const auto& p2 = mesh.positions[t[2]];
  const double a[3] = {double{p1[0]} - p0[0], double{p1[1]} - p0[1], double{p1[2]} - p0[2]};
  const double b[3] = {double{p2[0]} - p0[0], double{p2[1]} - p0[1], double{p2[2]} - p0[2]};
  return a[1] * b[2] - a[2] * b[1] == 0.0 && a[2] * b[0] - a[0] * b[2] == 0.0 &&
         a[0] * b[1] - a[1] * b[0] == 0.0;
}

using core::find_root;

}  // namespace

std::vector<std::string> Validity::problems() const {
  std::vector<std::string> lines;
  if (check.boundary_edges > 0) {
    lines.push_back(count_line(check.boundary_edges, "boundary edges (not closed)"));
  }
  if (check.non_manifold_edges > 0) {
    lines.push_back(count_line(check.non_manifold_edges, "edges in more than two triangles"));
  }
  if (check.non_manifold_vertices > 0) {
    lines.push_back(count_line(check.non_manifold_vertices, "non-manifold vertices"));
  }
  if (check.inconsistent_edges > 0) {
    lines.push_back(count_line(check.inconsistent_edges, "inconsistently oriented edges"));
  }
  if (check.degenerate_triangles > 0) {
    lines.push_back(count_line(check.degenerate_triangles, "degenerate triangles"));
  }
  return lines;
}

Validity check_validity(const core::TriangleMesh& mesh, unsigned threads) {
  return {core::check_mesh(mesh, threads)};
}

RepairReport repair_mesh(core::TriangleMesh& mesh) {
  RepairReport report;
  const std::size_t n = mesh.positions.size();

  // 1. Triangles with a repeated index carry no area and no topology.
  std::erase_if(mesh.triangles, [&](const auto& t) {
    assert(t[0] < n && t[1] < n && t[2] < n);
    if (!has_repeated_index(t)) return false;
    ++report.removed_repeated_index_triangles;
    return true;
  });

  // 2. Zero-length edges of zero-area triangles: merge the two ends (into the smaller
  //    index), which moves nothing. The triangles on such an edge then repeat an index.
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  for (const auto& t : mesh.triangles) {
    if (!has_zero_area(mesh, t)) continue;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k];
      const std::uint32_t b = t[(k + 1) % 3];
      if (mesh.positions[a] != mesh.positions[b]) continue;
      const std::uint32_t ra = find_root(parent, a);
      const std::uint32_t rb = find_root(parent, b);
      if (ra == rb) continue;
      parent[std::max(ra, rb)] = std::min(ra, rb);
      ++report.collapsed_zero_length_edges;
    }
  }
  if (report.collapsed_zero_length_edges > 0) {
    for (auto& t : mesh.triangles) {
      for (std::uint32_t& v : t) v = find_root(parent, v);
    }
    report.removed_collapsed_triangles = std::erase_if(mesh.triangles, has_repeated_index);
  }

  // 3. Vertices nothing uses any more.
  report.removed_unreferenced_vertices = remove_unreferenced_vertices(mesh);

  for (const auto& t : mesh.triangles) {
    if (has_zero_area(mesh, t)) ++report.remaining_degenerate_triangles;
  }
  report.validity = check_validity(mesh);
  return report;
}

}  // namespace typemerge::mesh
