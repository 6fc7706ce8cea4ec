// to_patient: voxel index space → patient LPS millimetres for a TriangleMesh.
#include "core/mesh.h"

#include <cassert>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace typemerge::core {

void to_patient(TriangleMesh& mesh, const IndexToPatient& geometry) {
  const double det = geometry.determinant();
  assert(det != 0.0);

  for (auto& p : mesh.positions) {
    const Vec3 q = geometry.apply(p[0], p[1], p[2]);
    p = {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2])};
  }

  // The linear part M has the axes as columns (patient = origin + M·index). A gradient
  // transforms with M^{-T}; its rows are the cofactor vectors, each divided by det. The common
  // factor 1/det only scales, but its sign matters, so keep it.
  const std::array<Vec3, 3> cof = geometry.cofactor_rows();
  for (auto& n : mesh.normals) {
    Vec3 m{0, 0, 0};
    for (int c = 0; c < 3; ++c) {
      m[c] = (cof[0][c] * n[0] + cof[1][c] * n[1] + cof[2][c] * n[2]) / det;
    }
    const double length = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
    if (length > 0.0) {
      n = {static_cast<float>(m[0] / length), static_cast<float>(m[1] / length),
           static_cast<float>(m[2] / length)};
    }
  }

  if (det < 0.0) {
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  }
}

std::array<double, 3> triangle_area_vector(const TriangleMesh& mesh,
                                           const std::array<std::uint32_t, 3>& triangle) {
  const auto& p0 = mesh.positions[triangle[0]];
  const auto& p1 = mesh.positions[triangle[1]];
  const auto& p2 = mesh.positions[triangle[2]];
  const double a[3] = {double{p1[0]} - p0[0], double{p1[1]} - p0[1], double{p1[2]} - p0[2]};
  const double b[3] = {double{p2[0]} - p0[0], double{p2[1]} - p0[1], double{p2[2]} - p0[2]};
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

std::array<double, 3> facet_normal(const TriangleMesh& mesh,
                                   const std::array<std::uint32_t, 3>& triangle) {
  std::array<double, 3> n = triangle_area_vector(mesh, triangle);
  const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (length > 0) {
    for (double& x : n) x /= length;
  }
  return n;
}

std::size_t remove_unreferenced_vertices(TriangleMesh& mesh) {
  const std::size_t n = mesh.positions.size();
  constexpr std::uint32_t kUnused = UINT32_MAX;
  std::vector<std::uint32_t> new_index(n, kUnused);
  for (const auto& t : mesh.triangles) {
    for (const std::uint32_t v : t) {
      assert(v < n);
      new_index[v] = 0;
    }
  }
  const bool has_normals = mesh.normals.size() == n;
  std::uint32_t next = 0;
  for (std::size_t v = 0; v < n; ++v) {
    if (new_index[v] == kUnused) continue;
    new_index[v] = next;
    mesh.positions[next] = mesh.positions[v];
    if (has_normals) mesh.normals[next] = mesh.normals[v];
    ++next;
  }
  mesh.positions.resize(next);
  if (has_normals) mesh.normals.resize(next);
  for (auto& t : mesh.triangles) {
    for (std::uint32_t& v : t) v = new_index[v];
  }
  return n - next;
}

BoundingBox bounding_box(const TriangleMesh& mesh) {
  BoundingBox box;
  for (const auto& p : mesh.positions) {
    for (int c = 0; c < 3; ++c) {
      box.min[c] = std::min(box.min[c], double{p[c]});
      box.max[c] = std::max(box.max[c], double{p[c]});
    }
  }
  return box;
}

}  // namespace typemerge::core
