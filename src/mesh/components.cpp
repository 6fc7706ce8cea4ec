// Components by union-find over vertices; containment of one shell in another by the parity
// of ray crossings (Möller & Trumbore 1997 ray–triangle test) along a fixed, deliberately
// irrational direction, so rays through edges and vertices of lattice meshes are unlikely.
#include "mesh/components.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "core/union_find.h"

namespace typemerge::mesh {
namespace {

using Point = std::array<double, 3>;

Point to_point(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

struct Components {
  std::size_t count = 0;
  std::vector<std::uint32_t> of_triangle;  // component label per triangle
  std::vector<double> volume;              // signed, per label
  std::vector<std::size_t> triangles;      // per label
  std::vector<Point> box_min, box_max;     // per label
  std::vector<std::uint32_t> some_vertex;  // per label
};

using core::find_root;

Components label_components(const core::TriangleMesh& mesh) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  for (const auto& t : mesh.triangles) {
    assert(t[0] < n && t[1] < n && t[2] < n);
    for (int k = 1; k < 3; ++k) {
      const std::uint32_t a = find_root(parent, t[0]);
      const std::uint32_t b = find_root(parent, t[k]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }

  Components c;
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> label_of_root(n, kNone);
  c.of_triangle.resize(mesh.triangles.size());
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    const std::uint32_t root = find_root(parent, t[0]);
    if (label_of_root[root] == kNone) {
      label_of_root[root] = static_cast<std::uint32_t>(c.count++);
      c.volume.push_back(0.0);
      c.triangles.push_back(0);
      c.box_min.push_back({kInf, kInf, kInf});
      c.box_max.push_back({-kInf, -kInf, -kInf});
      c.some_vertex.push_back(t[0]);
    }
    const std::uint32_t label = label_of_root[root];
    c.of_triangle[i] = label;
    ++c.triangles[label];
    const Point p0 = to_point(mesh.positions[t[0]]);
    const Point p1 = to_point(mesh.positions[t[1]]);
    const Point p2 = to_point(mesh.positions[t[2]]);
    // Signed volume of the tetrahedron (origin, p0, p1, p2), as in core::check_mesh.
    c.volume[label] += (p0[0] * (p1[1] * p2[2] - p1[2] * p2[1]) +
                        p0[1] * (p1[2] * p2[0] - p1[0] * p2[2]) +
                        p0[2] * (p1[0] * p2[1] - p1[1] * p2[0])) /
                       6.0;
    for (const Point& p : {p0, p1, p2}) {
      for (int k = 0; k < 3; ++k) {
        c.box_min[label][k] = std::min(c.box_min[label][k], p[k]);
        c.box_max[label][k] = std::max(c.box_max[label][k], p[k]);
      }
    }
  }
  return c;
}

// Removes the triangles whose component is marked in `remove`, then unused vertices.
ComponentReport remove_components(core::TriangleMesh& mesh, const Components& c,
                                  const std::vector<bool>& remove) {
  ComponentReport report;
  report.components_before = c.count;
  for (std::size_t label = 0; label < c.count; ++label) {
    if (remove[label]) {
      ++report.removed_components;
      report.removed_triangles += c.triangles[label];
      report.removed_volume += std::abs(c.volume[label]);
    } else {
      report.kept_volume += c.volume[label];
    }
  }
  report.components_after = c.count - report.removed_components;
  if (report.removed_components > 0) {
    std::size_t next = 0;
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
      if (!remove[c.of_triangle[i]]) mesh.triangles[next++] = mesh.triangles[i];
    }
    mesh.triangles.resize(next);
    remove_unreferenced_vertices(mesh);
  }
  report.validity = check_validity(mesh);
  return report;
}

Point cross(const Point& a, const Point& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Point sub(const Point& a, const Point& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

// Does the ray origin + t·direction, t > 0, cross triangle (p0, p1, p2)? Möller–Trumbore.
bool ray_hits(const Point& origin, const Point& direction, const Point& p0, const Point& p1,
              const Point& p2) {
  const Point e1 = sub(p1, p0);
  const Point e2 = sub(p2, p0);
  const Point h = cross(direction, e2);
  const double det = dot(e1, h);
  if (det == 0.0) return false;  // ray parallel to the plane
  const double inv = 1.0 / det;
  const Point s = sub(origin, p0);
  const double u = dot(s, h) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Point q = cross(s, e1);
  const double v = dot(direction, q) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  return dot(e2, q) * inv > 0.0;
}

bool box_inside(const Components& c, std::size_t inner, std::size_t outer) {
  for (int k = 0; k < 3; ++k) {
    if (c.box_min[inner][k] < c.box_min[outer][k] || c.box_max[inner][k] > c.box_max[outer][k]) {
      return false;
    }
  }
  return true;
}

}  // namespace

ComponentReport keep_largest_component(core::TriangleMesh& mesh) {
  const Components c = label_components(mesh);
  std::size_t largest = 0;
  for (std::size_t label = 1; label < c.count; ++label) {
    const double size = std::abs(c.volume[label]);
    const double best = std::abs(c.volume[largest]);
    if (size > best || (size == best && c.triangles[label] > c.triangles[largest])) {
      largest = label;
    }
  }
  std::vector<bool> remove(c.count, true);
  if (c.count > 0) remove[largest] = false;
  return remove_components(mesh, c, remove);
}

ComponentReport remove_small_components(core::TriangleMesh& mesh, double min_volume) {
  assert(min_volume >= 0.0);
  const Components c = label_components(mesh);
  std::vector<bool> remove(c.count);
  for (std::size_t label = 0; label < c.count; ++label) {
    remove[label] = std::abs(c.volume[label]) < min_volume;
  }
  return remove_components(mesh, c, remove);
}

ComponentReport fill_cavities(core::TriangleMesh& mesh) {
  const Components c = label_components(mesh);
  std::vector<bool> remove(c.count);
  for (std::size_t label = 0; label < c.count; ++label) remove[label] = c.volume[label] < 0.0;

  // Positive shells inside another positive shell. Candidate containers must be larger and
  // hold the candidate's bounding box; the crossing count uses the container's triangles.
  std::vector<std::vector<std::uint32_t>> triangles_of(c.count);
  const Point direction = {0.5773502691896258, 0.5612486080160912, 0.5929270612815711};
  for (std::size_t inner = 0; inner < c.count; ++inner) {
    if (remove[inner]) continue;
    const Point origin = to_point(mesh.positions[c.some_vertex[inner]]);
    for (std::size_t outer = 0; outer < c.count && !remove[inner]; ++outer) {
      if (outer == inner || c.volume[outer] <= c.volume[inner] || !box_inside(c, inner, outer)) {
        continue;
      }
      if (triangles_of[outer].empty()) {
        for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
          if (c.of_triangle[i] == outer) triangles_of[outer].push_back(static_cast<std::uint32_t>(i));
        }
      }
      std::size_t crossings = 0;
      for (const std::uint32_t i : triangles_of[outer]) {
        const auto& t = mesh.triangles[i];
        if (ray_hits(origin, direction, to_point(mesh.positions[t[0]]),
                     to_point(mesh.positions[t[1]]), to_point(mesh.positions[t[2]]))) {
          ++crossings;
        }
      }
      if (crossings % 2 == 1) remove[inner] = true;
    }
  }
  return remove_components(mesh, c, remove);
}

}  // namespace typemerge::mesh
