// Components by union-find over vertices; containment of one shell in another by the parity
// of ray crossings (core/ray_parity.h).
#include "mesh/components.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <span>
#include <vector>

#include "core/mesh_checks.h"
#include "core/ray_parity.h"
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

// Labels are numbered in the order of each component's first triangle. Unions point the larger
// root at the smaller, so parent[v] <= v and one pass in increasing v flattens the forest;
// boxes are then taken per vertex (each once, not once per triangle around it): together
// 19-29 -> 13-15 ms on the abdomen's 480 k bone triangles (convert --report, 2 threads).
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
  for (std::size_t v = 0; v < n; ++v) parent[v] = parent[parent[v]];

  Components c;
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> label(n, kNone);
  c.of_triangle.resize(mesh.triangles.size());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    const std::uint32_t root = parent[t[0]];
    if (label[root] == kNone) {
      label[root] = static_cast<std::uint32_t>(c.count++);
      c.some_vertex.push_back(t[0]);
    }
    c.of_triangle[i] = label[root];
  }
  // From here on, label[v] is the label of v's component (kNone: v is in no triangle).
  for (std::size_t v = 0; v < n; ++v) label[v] = label[parent[v]];
  c.volume.assign(c.count, 0.0);
  c.triangles.assign(c.count, 0);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  c.box_min.assign(c.count, {kInf, kInf, kInf});
  c.box_max.assign(c.count, {-kInf, -kInf, -kInf});
  for (std::size_t v = 0; v < n; ++v) {
    if (label[v] == kNone) continue;
    const Point p = to_point(mesh.positions[v]);
    for (int k = 0; k < 3; ++k) {
      c.box_min[label[v]][k] = std::min(c.box_min[label[v]][k], p[k]);
      c.box_max[label[v]][k] = std::max(c.box_max[label[v]][k], p[k]);
    }
  }
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    const std::uint32_t l = c.of_triangle[i];
    ++c.triangles[l];
    const Point p0 = to_point(mesh.positions[t[0]]);
    const Point p1 = to_point(mesh.positions[t[1]]);
    const Point p2 = to_point(mesh.positions[t[2]]);
    // Signed volume of the tetrahedron (origin, p0, p1, p2), as in core::check_mesh.
    c.volume[l] += (p0[0] * (p1[1] * p2[2] - p1[2] * p2[1]) +
                    p0[1] * (p1[2] * p2[0] - p1[0] * p2[2]) +
                    p0[2] * (p1[0] * p2[1] - p1[1] * p2[0])) /
                   6.0;
  }
  return c;
}

// Removes the triangles whose component is marked in `remove`, then unused vertices.
ComponentReport remove_components(core::TriangleMesh& mesh, const Components& c,
                                  const std::vector<bool>& remove,
                                  const core::MeshCheck* checked, unsigned threads) {
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
  const bool known = checked != nullptr && checked->closed_manifold() &&
                     checked->triangles == c.of_triangle.size() &&
                     checked->components == c.count;
  if (!known) {
    report.validity = check_validity(mesh, threads);
  } else if (report.removed_components == 0) {
    report.validity = {*checked};
  } else {
    report.validity = {
        core::check_after_removing_components(mesh, *checked, report.removed_components, threads)};
  }
  return report;
}

bool box_inside(const Components& c, std::size_t inner, std::size_t outer) {
  for (int k = 0; k < 3; ++k) {
    if (c.box_min[inner][k] < c.box_min[outer][k] || c.box_max[inner][k] > c.box_max[outer][k]) {
      return false;
    }
  }
  return true;
}

// Is one shell inside another? The parity of the crossings of a ray from a vertex of the inner
// shell with the outer shell's triangles (core/ray_parity.h), each outer shell's triangles
// bucketed once by their shadows along the ray (a skeleton's main shell has hundreds of
// cavities to test against its 300 k triangles: 7.4 s for the abdomen's bone by testing every
// triangle).
class Containment {
 public:
  Containment(const core::TriangleMesh& mesh, const Components& c)
      : mesh_(mesh), c_(c), parity_(c.count), first_(c.count + 1, 0) {
    // Triangles by component (CSR), once: the grids of many shells then cost their own size.
    for (std::uint32_t label : c.of_triangle) ++first_[label + 1];
    for (std::size_t k = 0; k < c.count; ++k) first_[k + 1] += first_[k];
    of_component_.resize(c.of_triangle.size());
    std::vector<std::uint32_t> fill(first_.begin(), first_.end() - 1);
    for (std::uint32_t i = 0; i < c.of_triangle.size(); ++i) {
      of_component_[fill[c.of_triangle[i]]++] = i;
    }
  }

  bool inside(std::size_t inner, std::size_t outer) {
    if (inner == outer || !box_inside(c_, inner, outer)) return false;
    std::unique_ptr<core::RayParity>& parity = parity_[outer];
    if (!parity) {
      parity = std::make_unique<core::RayParity>(
          mesh_, std::span(of_component_).subspan(first_[outer], first_[outer + 1] - first_[outer]));
    }
    return parity->inside(to_point(mesh_.positions[c_.some_vertex[inner]]));
  }

 private:
  const core::TriangleMesh& mesh_;
  const Components& c_;
  std::vector<std::unique_ptr<core::RayParity>> parity_;  // per outer shell, when first asked
  std::vector<std::uint32_t> first_;                      // CSR: component → its triangles
  std::vector<std::uint32_t> of_component_;
};

}  // namespace

ComponentReport keep_largest_component(core::TriangleMesh& mesh, Cavities cavities,
                                       const core::MeshCheck* checked, unsigned threads) {
  const Components c = label_components(mesh);
  // The largest solid: the outward shell enclosing the most volume. Cavity walls (negative
  // volume) compete only when there is no outward shell at all (an inside-out mesh).
  bool any_outward = false;
  for (std::size_t label = 0; label < c.count; ++label) any_outward |= c.volume[label] > 0.0;
  auto size_of = [&](std::size_t label) {
    return any_outward ? c.volume[label] : std::abs(c.volume[label]);
  };
  std::size_t largest = 0;
  for (std::size_t label = 1; label < c.count; ++label) {
    const double size = size_of(label);
    const double best = size_of(largest);
    if (size > best || (size == best && c.triangles[label] > c.triangles[largest])) {
      largest = label;
    }
  }
  std::vector<bool> remove(c.count, true);
  if (c.count == 0) return remove_components(mesh, c, remove, checked, threads);
  remove[largest] = false;
  if (!any_outward || cavities == Cavities::fill) {
    return remove_components(mesh, c, remove, checked, threads);
  }

  // Its cavities stay: a cavity wall whose innermost enclosing outward shell is the largest.
  // (A cavity of an island floating inside one of its cavities belongs to the island.)
  Containment containment(mesh, c);
  for (std::size_t cavity = 0; cavity < c.count; ++cavity) {
    if (c.volume[cavity] >= 0.0 || !containment.inside(cavity, largest)) continue;
    bool nearer_container = false;
    for (std::size_t shell = 0; shell < c.count && !nearer_container; ++shell) {
      nearer_container = shell != largest && c.volume[shell] > 0.0 &&
                         c.volume[shell] < c.volume[largest] &&
                         containment.inside(cavity, shell) && containment.inside(shell, largest);
    }
    remove[cavity] = nearer_container;
  }
  return remove_components(mesh, c, remove, checked, threads);
}

ComponentReport remove_small_components(core::TriangleMesh& mesh, double min_volume,
                                        const core::MeshCheck* checked, unsigned threads) {
  assert(min_volume >= 0.0);
  const Components c = label_components(mesh);
  std::vector<bool> remove(c.count);
  for (std::size_t label = 0; label < c.count; ++label) {
    remove[label] = std::abs(c.volume[label]) < min_volume;
  }
  return remove_components(mesh, c, remove, checked, threads);
}

ComponentReport fill_cavities(core::TriangleMesh& mesh, const core::MeshCheck* checked,
                              unsigned threads) {
  const Components c = label_components(mesh);
  std::vector<bool> remove(c.count);
  for (std::size_t label = 0; label < c.count; ++label) remove[label] = c.volume[label] < 0.0;

  // Positive shells inside another, larger positive shell.
  Containment containment(mesh, c);
  for (std::size_t inner = 0; inner < c.count; ++inner) {
    if (remove[inner]) continue;
    for (std::size_t outer = 0; outer < c.count && !remove[inner]; ++outer) {
      if (c.volume[outer] > c.volume[inner] && containment.inside(inner, outer)) {
        remove[inner] = true;
      }
    }
  }
  return remove_components(mesh, c, remove, checked, threads);
}

}  // namespace typemerge::mesh
