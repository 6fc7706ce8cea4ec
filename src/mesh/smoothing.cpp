// Umbrella operator over a compressed adjacency (CSR) built once from the unique edges; the
// steps run Jacobi-style (every vertex reads the previous positions), in double.
#include "mesh/smoothing.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/mesh_checks.h"
#include "mesh/normals.h"

namespace typemerge::mesh {
namespace {

struct Adjacency {
  std::vector<std::uint32_t> offsets;  // neighbours of v: [offsets[v], offsets[v + 1])
  std::vector<std::uint32_t> neighbours;
};

Adjacency build_adjacency(const core::TriangleMesh& mesh) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  edges.reserve(mesh.triangles.size() * 6);
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k];
      const std::uint32_t b = t[(k + 1) % 3];
      assert(a < n && b < n);
      if (a == b) continue;
      edges.emplace_back(a, b);
      edges.emplace_back(b, a);
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  Adjacency adjacency;
  adjacency.offsets.assign(n + 1, 0);
  adjacency.neighbours.reserve(edges.size());
  for (const auto& [a, b] : edges) {
    ++adjacency.offsets[a + 1];
    adjacency.neighbours.push_back(b);
  }
  for (std::size_t v = 0; v < n; ++v) adjacency.offsets[v + 1] += adjacency.offsets[v];
  return adjacency;
}

// p ← p + factor·(mean(neighbours) − p) for every vertex with neighbours.
void umbrella_step(const Adjacency& adjacency, double factor,
                   const std::vector<std::array<double, 3>>& from,
                   std::vector<std::array<double, 3>>& to) {
  for (std::size_t v = 0; v < from.size(); ++v) {
    const std::uint32_t begin = adjacency.offsets[v];
    const std::uint32_t end = adjacency.offsets[v + 1];
    if (begin == end) {
      to[v] = from[v];
      continue;
    }
    std::array<double, 3> mean{0.0, 0.0, 0.0};
    for (std::uint32_t i = begin; i < end; ++i) {
      const auto& q = from[adjacency.neighbours[i]];
      for (int k = 0; k < 3; ++k) mean[k] += q[k];
    }
    const double inv = 1.0 / static_cast<double>(end - begin);
    for (int k = 0; k < 3; ++k) to[v][k] = from[v][k] + factor * (mean[k] * inv - from[v][k]);
  }
}

}  // namespace

SmoothingReport smooth_mesh(core::TriangleMesh& mesh, const SmoothingOptions& options) {
  assert(options.iterations >= 0);
  assert(options.lambda > 0.0 && options.lambda <= 1.0);
  assert(options.pass_band > 0.0 && options.pass_band < 1.0 / options.lambda);

  SmoothingReport report;
  report.iterations = options.iterations;
  report.lambda = options.lambda;
  const bool taubin = options.method == SmoothingOptions::Method::taubin;
  report.mu = taubin ? 1.0 / (options.pass_band - 1.0 / options.lambda) : 0.0;
  report.volume_before = core::check_mesh(mesh).volume;

  const Adjacency adjacency = build_adjacency(mesh);
  std::vector<std::array<double, 3>> current(mesh.positions.size());
  for (std::size_t v = 0; v < current.size(); ++v) {
    const auto& p = mesh.positions[v];
    current[v] = {p[0], p[1], p[2]};
  }
  std::vector<std::array<double, 3>> next(current.size());
  for (int i = 0; i < options.iterations; ++i) {
    umbrella_step(adjacency, options.lambda, current, next);
    std::swap(current, next);
    if (taubin) {
      umbrella_step(adjacency, report.mu, current, next);
      std::swap(current, next);
    }
  }
  for (std::size_t v = 0; v < current.size(); ++v) {
    mesh.positions[v] = {static_cast<float>(current[v][0]), static_cast<float>(current[v][1]),
                         static_cast<float>(current[v][2])};
  }
  compute_vertex_normals(mesh);

  report.validity = check_validity(mesh);
  report.volume_after = report.validity.check.volume;
  if (report.volume_before != 0.0) {
    report.relative_volume_change =
        (report.volume_after - report.volume_before) / std::abs(report.volume_before);
  }
  return report;
}

}  // namespace typemerge::mesh
