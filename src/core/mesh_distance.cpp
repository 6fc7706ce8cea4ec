// Vertex-to-surface distances over a uniform grid of triangle buckets (see mesh_distance.h).
#include "core/mesh_distance.h"

#include <cassert>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "core/triangle_grid.h"

namespace typemerge::core {

namespace {

using P3 = std::array<double, 3>;

P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot3(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
P3 cross3(const P3& a, const P3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

P3 to_p3(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }


}  // namespace

namespace detail {

double point_segment_distance_squared(const P3& p, const P3& a, const P3& b) {
  const P3 ab = sub(b, a);
  const P3 ap = sub(p, a);
  const double len2 = dot3(ab, ab);
  double t = len2 > 0.0 ? dot3(ap, ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const P3 q = {a[0] + t * ab[0] - p[0], a[1] + t * ab[1] - p[1], a[2] + t * ab[2] - p[2]};
  return dot3(q, q);
}

double point_triangle_distance_squared(const P3& p, const P3& a, const P3& b, const P3& c) {
  const P3 ab = sub(b, a);
  const P3 ac = sub(c, a);
  const P3 n = cross3(ab, ac);
  const double n2 = dot3(n, n);
  const double scale = std::max({dot3(ab, ab), dot3(ac, ac), 1e-300});
  if (n2 <= 1e-24 * scale * scale) {
    // Degenerate: the triangle is (at most) its three edges.
    return std::min({point_segment_distance_squared(p, a, b),
                     point_segment_distance_squared(p, b, c),
                     point_segment_distance_squared(p, c, a)});
  }
  // Inside the prism over the triangle: distance to the plane; else to the nearest edge.
  const P3 ap = sub(p, a);
  const P3 bp = sub(p, b);
  const P3 cp = sub(p, c);
  const double wa = dot3(cross3(sub(c, b), bp), n);
  const double wb = dot3(cross3(sub(a, c), cp), n);
  const double wc = dot3(cross3(ab, ap), n);
  if (wa >= 0.0 && wb >= 0.0 && wc >= 0.0) {
    const double h = dot3(ap, n);
    return h * h / n2;
  }
  return std::min({point_segment_distance_squared(p, a, b),
                   point_segment_distance_squared(p, b, c),
                   point_segment_distance_squared(p, c, a)});
}

}  // namespace detail

namespace {

// Calls visit(chunk, i, distance) for every point i, in fixed chunks of kNearestChunk points
// spread over the threads, each worker with its own query stamps over `to`'s triangles.
// Precondition: `to` has triangles.
constexpr std::size_t kNearestChunk = 4096;

template <typename Visit>
void visit_nearest(std::span<const std::array<float, 3>> points, const TriangleMesh& to,
                   unsigned threads, double cap, const Visit& visit) {
  const detail::TriangleGrid grid(to);
  const std::size_t chunks = (points.size() + kNearestChunk - 1) / kNearestChunk;
  const unsigned n_threads = detail::resolve_threads(threads);
  // Per worker: the query stamp of every triangle of `to`, and the current query number.
  std::vector<std::vector<std::uint32_t>> stamps(n_threads);
  std::vector<std::uint32_t> queries(n_threads, 0);
  detail::run_parallel(chunks, n_threads, [&](std::size_t k, unsigned w) {
    std::vector<std::uint32_t>& stamp = stamps[w];
    std::uint32_t& query = queries[w];
    if (stamp.empty()) stamp.assign(to.triangles.size(), 0);
    const std::size_t end = std::min(points.size(), (k + 1) * kNearestChunk);
    // Points in order lie near each other (a mesh's vertices, a triangle's samples), so each
    // search starts from the previous point's nearest triangle; the distances are the same.
    std::uint32_t hint = std::numeric_limits<std::uint32_t>::max();
    for (std::size_t v = k * kNearestChunk; v < end; ++v) {
      if (++query == 0) {  // wrapped: reset the stamps
        std::fill(stamp.begin(), stamp.end(), 0);
        query = 1;
      }
      visit(k, v, std::sqrt(grid.nearest_squared_from(to_p3(points[v]), stamp, query, cap, hint)));
    }
  });
}

}  // namespace

MeshDistance vertex_to_mesh_distance(const TriangleMesh& from, const TriangleMesh& to,
                                     unsigned threads) {
  MeshDistance out;
  out.points = from.positions.size();
  if (from.positions.empty()) return out;
  if (to.triangles.empty()) {
    out.max = out.mean = std::numeric_limits<double>::infinity();
    return out;
  }
  // Fixed chunks summed in chunk order: the mean is the same for any thread count.
  const std::size_t chunks = (from.positions.size() + kNearestChunk - 1) / kNearestChunk;
  std::vector<double> chunk_max(chunks, 0.0);
  std::vector<double> chunk_sum(chunks, 0.0);
  visit_nearest(from.positions, to, threads, std::numeric_limits<double>::infinity(),
                [&](std::size_t k, std::size_t, double d) {
                  chunk_max[k] = std::max(chunk_max[k], d);
                  chunk_sum[k] += d;
                });
  double sum = 0.0;
  for (std::size_t k = 0; k < chunks; ++k) {
    out.max = std::max(out.max, chunk_max[k]);
    sum += chunk_sum[k];
  }
  out.mean = sum / static_cast<double>(from.positions.size());
  return out;
}

std::vector<float> point_to_mesh_distances(std::span<const std::array<float, 3>> points,
                                           const TriangleMesh& to, unsigned threads, double cap) {
  std::vector<float> distances(points.size(), std::numeric_limits<float>::infinity());
  if (points.empty() || to.triangles.empty()) return distances;
  visit_nearest(points, to, threads, cap, [&](std::size_t, std::size_t v, double d) {
    distances[v] = static_cast<float>(d);
  });
  return distances;
}

double max_vertex_distance(const TriangleMesh& from, const TriangleMesh& to, unsigned threads) {
  return vertex_to_mesh_distance(from, to, threads).max;
}

double SymmetricMeshDistance::mean() const {
  const double n = static_cast<double>(a_to_b.points + b_to_a.points);
  if (n == 0.0) return 0.0;
  return (a_to_b.mean * static_cast<double>(a_to_b.points) +
          b_to_a.mean * static_cast<double>(b_to_a.points)) /
         n;
}

SymmetricMeshDistance mesh_distance(const TriangleMesh& a, const TriangleMesh& b,
                                    unsigned threads) {
  return {vertex_to_mesh_distance(a, b, threads), vertex_to_mesh_distance(b, a, threads)};
}

TriangleMesh surface_samples(const TriangleMesh& mesh, double spacing) {
  assert(spacing > 0.0);
  TriangleMesh points;
  points.positions = mesh.positions;
  for (const auto& t : mesh.triangles) {
    const auto& p0 = mesh.positions[t[0]];
    const auto& p1 = mesh.positions[t[1]];
    const auto& p2 = mesh.positions[t[2]];
    auto length = [](const std::array<float, 3>& u, const std::array<float, 3>& v) {
      const double d[3] = {double{u[0]} - v[0], double{u[1]} - v[1], double{u[2]} - v[2]};
      return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    };
    const double longest = std::max({length(p0, p1), length(p1, p2), length(p2, p0)});
    const int k = std::max(1, static_cast<int>(std::ceil(longest / spacing)));
    // Interior and edge points of the lattice (the corners are the mesh's vertices).
    for (int i = 0; i <= k; ++i) {
      for (int j = 0; i + j <= k; ++j) {
        if ((i == 0 && j == 0) || (i == k) || (j == k)) continue;
        const double u = double(i) / k;
        const double v = double(j) / k;
        const double w = 1.0 - u - v;
        std::array<float, 3> q;
        for (int c = 0; c < 3; ++c) q[c] = static_cast<float>(w * p0[c] + u * p1[c] + v * p2[c]);
        points.positions.push_back(q);
      }
    }
  }
  return points;
}

namespace {

// SplitMix64 (Steele, Lea and Flood 2014): a well-mixed 64-bit value from any state, so that
// consecutive triangle indices start unrelated streams.
std::uint64_t split_mix(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform in [0, 1).
double unit(std::uint64_t& state) { return static_cast<double>(split_mix(state) >> 11) * 0x1p-53; }

}  // namespace

TriangleMesh area_samples(const TriangleMesh& mesh, double per_unit_area, std::uint64_t seed) {
  assert(per_unit_area >= 0.0);
  std::vector<double> areas(mesh.triangles.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const P3 a = to_p3(mesh.positions[tri[0]]);
    const P3 n =
        cross3(sub(to_p3(mesh.positions[tri[1]]), a), sub(to_p3(mesh.positions[tri[2]]), a));
    areas[t] = 0.5 * std::sqrt(dot3(n, n));
    total += areas[t];
  }
  TriangleMesh points;
  const auto spread = static_cast<std::size_t>(std::ceil(total * per_unit_area));
  points.positions.reserve(mesh.positions.size() + mesh.triangles.size() + spread);
  points.positions = mesh.positions;
  for (const auto& tri : mesh.triangles) {
    std::array<float, 3> c;
    for (int k = 0; k < 3; ++k) {
      c[k] = static_cast<float>((double{mesh.positions[tri[0]][k]} + mesh.positions[tri[1]][k] +
                                 mesh.positions[tri[2]][k]) /
                                3.0);
    }
    points.positions.push_back(c);
  }
  double running = 0.0;
  std::size_t given = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    running += areas[t] * per_unit_area;
    std::size_t due = std::min(spread, static_cast<std::size_t>(std::ceil(running)));
    if (t + 1 == mesh.triangles.size()) due = spread;  // what the running sum's rounding left
    if (due <= given) continue;
    const auto& tri = mesh.triangles[t];
    const P3 a = to_p3(mesh.positions[tri[0]]);
    const P3 b = to_p3(mesh.positions[tri[1]]);
    const P3 c = to_p3(mesh.positions[tri[2]]);
    std::uint64_t state = seed ^ (0xd1b54a32d192ed03ULL * (t + 1));
    for (; given < due; ++given) {
      // Uniform over the triangle: √r1 along the way from a to the edge bc, r2 along bc.
      const double r1 = std::sqrt(unit(state));
      const double r2 = unit(state);
      const double wa = 1.0 - r1;
      const double wb = r1 * (1.0 - r2);
      const double wc = r1 * r2;
      std::array<float, 3> q;
      for (int k = 0; k < 3; ++k) q[k] = static_cast<float>(wa * a[k] + wb * b[k] + wc * c[k]);
      points.positions.push_back(q);
    }
  }
  return points;
}

SymmetricMeshDistance area_sampled_distance(const TriangleMesh& a, const TriangleMesh& b,
                                            double per_unit_area, unsigned threads,
                                            std::uint64_t seed) {
  return {vertex_to_mesh_distance(area_samples(a, per_unit_area, seed), b, threads),
          vertex_to_mesh_distance(area_samples(b, per_unit_area, seed), a, threads)};
}

SymmetricMeshDistance surface_distance(const TriangleMesh& a, const TriangleMesh& b,
                                       double spacing, unsigned threads) {
  return {vertex_to_mesh_distance(surface_samples(a, spacing), b, threads),
          vertex_to_mesh_distance(surface_samples(b, spacing), a, threads)};
}

}  // namespace typemerge::core
