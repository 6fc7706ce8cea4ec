#include "mesh/meshopt_decimation.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "mesh/normals.h"
#include "mesh/validity.h"

namespace typemerge::mesh {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", value);
  return text;
}

// meshopt reads both buffers as flat arrays of floats and of indices.
static_assert(sizeof(std::array<float, 3>) == 3 * sizeof(float));
static_assert(sizeof(std::array<std::uint32_t, 3>) == 3 * sizeof(unsigned int));

// One meshopt_simplify run over the triangles of `input` that touch no `locked` vertex, with
// the border of that region locked (meshopt_SimplifyLockBorder), so the triangles kept as
// they are still meet the simplified rest edge for edge. Returns the kept triangles and the
// simplified rest over the input's vertices, the unused ones removed (no normals yet).
core::TriangleMesh simplify_once(const core::TriangleMesh& input,
                                 const std::vector<std::uint8_t>& locked,
                                 std::size_t target_triangles, float relative_error) {
  core::TriangleMesh result;
  std::vector<std::array<std::uint32_t, 3>> rest;
  rest.reserve(input.triangles.size());
  for (const auto& t : input.triangles) {
    const bool keep = locked[t[0]] != 0 || locked[t[1]] != 0 || locked[t[2]] != 0;
    (keep ? result.triangles : rest).push_back(t);
  }
  const std::size_t kept = result.triangles.size();
  const std::size_t rest_target = target_triangles > kept ? target_triangles - kept : 0;
  std::size_t count = 0;
  std::vector<unsigned int> simplified(3 * rest.size());  // the worst case, as meshopt asks
  if (!rest.empty()) {
    count = meshopt_simplify(simplified.data(), rest.front().data(), 3 * rest.size(),
                             input.positions.front().data(), input.positions.size(),
                             sizeof(input.positions.front()),
                             std::min(3 * rest_target, 3 * rest.size()), relative_error,
                             kept > 0 ? meshopt_SimplifyLockBorder : 0, nullptr);
  }
  result.positions = input.positions;
  result.triangles.resize(kept + count / 3);
  if (count > 0) {
    std::memcpy(result.triangles.data() + kept, simplified.data(), count * sizeof(unsigned int));
  }
  remove_unreferenced_vertices(result);
  return result;
}

// What checks 2-4 of the header found in one result: its triangles that are wrong (on an edge
// not used exactly twice in opposite directions, around a vertex whose triangles are not one
// fan, of zero area, crossing another) and the points too far from the other surface.
struct Problems {
  std::vector<std::uint8_t> bad_triangles;  // per triangle of the result
  std::vector<std::array<float, 3>> far_points;
  std::size_t topology = 0, degenerate = 0, new_crossings = 0;
  std::size_t crossings = 0;  // crossing pairs of the result (counted when nothing else is wrong)
  double distance = 0.0;      // the sampled two-sided distance, capped at 2 max_error
  bool any() const { return topology + degenerate + new_crossings + far_points.size() > 0; }
  std::string describe() const {
    std::string text;
    const auto add = [&text](std::size_t n, const std::string& what) {
      if (n > 0) text += (text.empty() ? "" : ", ") + std::to_string(n) + " " + what;
    };
    add(topology, "triangles on non-manifold edges or vertices");
    add(degenerate, "zero-area triangles");
    add(new_crossings, "crossing pairs");
    add(far_points.size(), "points farther than max_error (sampled distance " + number(distance) +
                               " mm)");
    return text;
  }
};

// Marks the triangles on an edge not used exactly twice in opposite directions, and those
// around a vertex whose corners do not form one closed fan. Returns how many it marked.
std::size_t mark_topology(const core::TriangleMesh& mesh, std::vector<std::uint8_t>& bad) {
  const std::size_t n = mesh.triangles.size();
  std::size_t marked = 0;
  const auto mark = [&](std::uint32_t t) {
    marked += bad[t] == 0 ? 1 : 0;
    bad[t] = 1;
  };
  struct Edge {  // a directed edge, keyed by its undirected one
    std::uint32_t lo, hi, triangle;
    bool forward;
  };
  std::vector<Edge> edges;
  edges.reserve(3 * n);
  for (std::uint32_t t = 0; t < n; ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = tri[k], b = tri[(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), t, a < b});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) {
    return x.lo != y.lo ? x.lo < y.lo : x.hi < y.hi;
  });
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
    if (j - i != 2 || edges[i].forward == edges[i + 1].forward) {
      for (std::size_t k = i; k < j; ++k) mark(edges[k].triangle);
    }
    i = j;
  }
  // Each vertex's corners (next, previous) by vertex; one closed fan when following `next`
  // from the first corner comes back to it after visiting every corner.
  std::vector<std::uint32_t> first(mesh.positions.size() + 1, 0);
  for (const auto& tri : mesh.triangles) {
    for (const auto v : tri) ++first[v + 1];
  }
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) first[v + 1] += first[v];
  struct Corner {
    std::uint32_t next, prev, triangle;
  };
  std::vector<Corner> corners(3 * n);
  std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
  for (std::uint32_t t = 0; t < n; ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) corners[fill[tri[k]]++] = {tri[(k + 1) % 3], tri[(k + 2) % 3], t};
  }
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const std::uint32_t begin = first[v], end = first[v + 1];
    if (begin == end) continue;
    std::uint32_t at = corners[begin].next;
    std::uint32_t steps = 1;
    bool open = false;
    while (at != corners[begin].prev && !open && steps <= end - begin) {
      open = true;
      for (std::uint32_t c = begin; c < end; ++c) {
        if (corners[c].prev == at) {
          at = corners[c].next;
          ++steps;
          open = false;
          break;
        }
      }
    }
    if (open || steps != end - begin) {
      for (std::uint32_t c = begin; c < end; ++c) mark(corners[c].triangle);
    }
  }
  return marked;
}

// Checks 2-4 of the header on `result`, made from `input` (whose crossing pairs are counted
// once, when a result has any, into `input_crossings`).
Problems find_problems(const core::TriangleMesh& input, const core::TriangleMesh& result,
                       const DecimationOptions& options, double spacing,
                       std::optional<std::size_t>& input_crossings) {
  Problems problems;
  problems.bad_triangles.assign(result.triangles.size(), 0);
  problems.topology = mark_topology(result, problems.bad_triangles);
  for (std::size_t t = 0; t < result.triangles.size(); ++t) {
    const auto area = core::triangle_area_vector(result, result.triangles[t]);
    if (area[0] == 0.0 && area[1] == 0.0 && area[2] == 0.0) {
      problems.bad_triangles[t] = 1;
      ++problems.degenerate;
    }
  }
  if (std::isfinite(options.max_error)) {
    const double cap = 2.0 * options.max_error;  // the search stops there: far points cost little
    const auto add_far = [&](std::span<const std::array<float, 3>> points,
                             const core::TriangleMesh& to) {
      const std::vector<float> d = core::point_to_mesh_distances(points, to, options.threads, cap);
      for (std::size_t i = 0; i < d.size(); ++i) {
        problems.distance = std::max(problems.distance, double{d[i]});
        if (d[i] > options.max_error) problems.far_points.push_back(points[i]);
      }
    };
    add_far(input.positions, result);
    add_far(core::surface_samples(result, spacing).positions, input);
  }
  if (problems.any()) return problems;
  const auto crossings = core::find_self_intersections(result);
  problems.crossings = crossings.pairs.size();
  if (problems.crossings > 0 && !input_crossings) {
    input_crossings = core::find_self_intersections(input).pairs.size();
  }
  if (problems.crossings > input_crossings.value_or(0)) {
    problems.new_crossings = problems.crossings;
    for (const auto& pair : crossings.pairs) {
      problems.bad_triangles[pair[0]] = problems.bad_triangles[pair[1]] = 1;
    }
  }
  return problems;
}

// Locks the input vertices within `radius` of the problems, so that the next pass keeps the
// input's triangles there. Returns how many vertices it newly locked.
std::size_t lock_around(const core::TriangleMesh& input, const core::TriangleMesh& result,
                        const Problems& problems, double radius, unsigned threads,
                        std::vector<std::uint8_t>& locked) {
  core::TriangleMesh spots;  // the bad triangles, and each far point as a one-point triangle
  spots.positions = result.positions;
  for (std::size_t t = 0; t < result.triangles.size(); ++t) {
    if (problems.bad_triangles[t] != 0) spots.triangles.push_back(result.triangles[t]);
  }
  // A far point as a small triangle at it (half the radius across), not as a point: the
  // distance grid sizes its cells by the mean edge.
  const auto half = static_cast<float>(0.5 * radius);
  for (const auto& p : problems.far_points) {
    const auto i = static_cast<std::uint32_t>(spots.positions.size());
    spots.positions.push_back(p);
    spots.positions.push_back({p[0] + half, p[1], p[2]});
    spots.positions.push_back({p[0], p[1] + half, p[2]});
    spots.triangles.push_back({i, i + 1, i + 2});
  }
  const std::vector<float> d =
      core::point_to_mesh_distances(input.positions, spots, threads, radius);
  std::size_t newly = 0;
  for (std::size_t v = 0; v < d.size(); ++v) {
    if (d[v] < radius && locked[v] == 0) {
      locked[v] = 1;
      ++newly;
    }
  }
  return newly;
}

// What makes `result` unacceptable beside `input` topologically, or nothing.
std::optional<std::string> topology_problem(const core::MeshCheck& result,
                                            const core::MeshCheck& input) {
  if (!result.closed_manifold()) {
    std::string text;
    for (const auto& line : Validity{result}.problems()) text += (text.empty() ? "" : ", ") + line;
    return text;
  }
  if (result.euler_characteristic != input.euler_characteristic) {
    return "Euler characteristic " + std::to_string(result.euler_characteristic) + ", input " +
           std::to_string(input.euler_characteristic);
  }
  if (result.components != input.components) {
    return std::to_string(result.components) + " components, input " +
           std::to_string(input.components);
  }
  return std::nullopt;
}

// Mean edge length of `mesh` (each triangle's three edges), the sampling spacing of check 4.
double mean_edge_length(const core::TriangleMesh& mesh) {
  double sum = 0.0;
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const auto& a = mesh.positions[t[k]];
      const auto& b = mesh.positions[t[(k + 1) % 3]];
      const double d[3] = {double{a[0]} - b[0], double{a[1]} - b[1], double{a[2]} - b[2]};
      sum += std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
  }
  return mesh.triangles.empty() ? 1.0 : sum / (3.0 * static_cast<double>(mesh.triangles.size()));
}

}  // namespace

DecimationReport decimate_with_meshopt(core::TriangleMesh& mesh,
                                       const DecimationOptions& options) {
  assert(options.max_error > 0.0);
  assert(std::isfinite(options.max_error) || options.target_triangles > 0);
  DecimationReport report;
  report.decimator = Decimator::meshopt;
  report.triangles_before = mesh.triangles.size();
  report.max_error = options.max_error;
  const auto refuse = [&report](std::string why) {
    report.fallback = std::move(why);
    return report;
  };

  auto start = Clock::now();
  const core::MeshCheck input = core::check_mesh(mesh, options.threads);
  report.meshopt.check_ms += ms_since(start);
  if (!input.closed_manifold()) {
    std::string text;
    for (const auto& line : Validity{input}.problems()) text += (text.empty() ? "" : ", ") + line;
    return refuse("input not closed manifold: " + text);
  }
  if (mesh.empty() ||
      (options.target_triangles > 0 && mesh.triangles.size() <= options.target_triangles)) {
    report.triangles_after = mesh.triangles.size();
    report.reached_target = options.target_triangles > 0;
    report.validity = Validity{input};
    return report;
  }

  // max_error in mm to meshopt's units: relative to the extent it rescales the mesh by, times
  // kErrorFactor since the quadric error is a mean and the largest distance exceeds it here
  // and there; those places are found by the checks and kept as they were in the next pass.
  const bool bounded = std::isfinite(options.max_error);
  const double scale = meshopt_simplifyScale(mesh.positions.front().data(), mesh.positions.size(),
                                             sizeof(mesh.positions.front()));
  const float relative = bounded ? static_cast<float>(kErrorFactor * options.max_error / scale)
                                 : std::numeric_limits<float>::max();
  const double spacing = mean_edge_length(mesh);
  std::vector<std::uint8_t> locked(mesh.positions.size(), 0);
  std::optional<std::size_t> input_crossings;  // counted only when a result has any

  for (int pass = 1; pass <= kMaxMeshoptPasses; ++pass) {
    report.meshopt.passes = pass;
    start = Clock::now();
    core::TriangleMesh result = simplify_once(mesh, locked, options.target_triangles, relative);
    report.meshopt.simplify_ms += ms_since(start);

    start = Clock::now();
    const Problems problems = find_problems(mesh, result, options, spacing, input_crossings);
    if (bounded) report.meshopt.sampled_error = problems.distance;
    report.meshopt.crossing_pairs = problems.crossings;
    if (problems.any()) {
      const std::string found = problems.describe();
      if (pass == kMaxMeshoptPasses) {
        report.meshopt.check_ms += ms_since(start);
        return refuse(found + " after " + std::to_string(pass) + " passes");
      }
      // Around each problem, the input's triangles within a few of its edges, wider each pass.
      const double radius = 2.0 * pass * spacing;
      const std::size_t newly =
          lock_around(mesh, result, problems, radius, options.threads, locked);
      report.meshopt.check_ms += ms_since(start);
      if (newly == 0) return refuse(found + " (nothing more to keep)");
      report.meshopt.notes.push_back("pass " + std::to_string(pass) + ": " + found + "; " +
                                     std::to_string(newly) + " input vertices kept around them");
      continue;
    }
    const core::MeshCheck check = core::check_mesh(result, options.threads);
    report.meshopt.check_ms += ms_since(start);
    if (auto problem = topology_problem(check, input)) return refuse(*problem);
    if (result.triangles.size() == mesh.triangles.size()) {
      return refuse("nothing reduced: every triangle kept around the problems of the passes");
    }

    for (const auto& t : mesh.triangles) {
      if (locked[t[0]] != 0 || locked[t[1]] != 0 || locked[t[2]] != 0) {
        ++report.meshopt.kept_triangles;
      }
    }
    compute_vertex_normals(result);
    mesh = std::move(result);
    report.triangles_after = mesh.triangles.size();
    report.reached_target = options.target_triangles > 0 &&
                            report.triangles_after <= options.target_triangles + 1;
    report.validity = Validity{check};
    return report;
  }
  assert(false && "every pass returns or continues to the next");
  return report;
}

}  // namespace typemerge::mesh
