// check_mesh: triangle corners bucketed by vertex (counting sort, O(n)), each vertex's link
// examined on its own for the vertex and its edges; components by union-find.
// detail::check_mesh_by_sorting is the first, simplest version (one global sort of the
// half-edges, a vector per vertex): it stays as the oracle the fast one is tested against.
// The fast one exists because the pipeline checks the mesh after every finishing step: on
// 600 k triangles the sorting version took 0.35 s.
#include "core/mesh_checks.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/union_find.h"

namespace typemerge::core {
namespace {

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  std::size_t find(std::size_t x) { return find_root(parent_, x); }
  void unite(std::size_t a, std::size_t b) { parent_[find(a)] = find(b); }

 private:
  std::vector<std::size_t> parent_;
};

// A vertex is manifold when its link (the edges opposite it in its triangles) is one simple
// path or one simple cycle: every link vertex has degree at most 2 and the link is connected.
bool link_is_disk_or_fan_general(std::vector<std::pair<std::uint32_t, std::uint32_t>>& link);

// The common case, without allocating: a vertex inside a closed, consistently oriented surface
// has a link that is one directed cycle. Following "first → second" from link[0] with distinct
// firsts returns to the start after exactly link.size() steps only then (and then the seconds
// are the firsts). Links longer than 32 go to the general test.
bool link_is_one_directed_cycle(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& link) {
  if (link.size() <= 32) {
    bool distinct = true;
    for (std::size_t i = 0; i < link.size() && distinct; ++i) {
      for (std::size_t j = i + 1; j < link.size(); ++j) {
        if (link[i].first == link[j].first) {
          distinct = false;
          break;
        }
      }
    }
    if (distinct) {
      const std::uint32_t start = link[0].first;
      std::uint32_t at = start;
      std::size_t steps = 0;
      while (steps <= link.size()) {
        std::size_t e = 0;
        while (e < link.size() && link[e].first != at) ++e;
        if (e == link.size()) break;
        at = link[e].second;
        ++steps;
        if (at == start) break;
      }
      if (at == start && steps == link.size()) return true;
    }
  }
  return false;
}

// Any link: sorted ends for the degrees, union-find for connectivity. The oracle uses only this.
bool link_is_disk_or_fan_general(std::vector<std::pair<std::uint32_t, std::uint32_t>>& link) {
  std::vector<std::uint32_t> ends;
  ends.reserve(link.size() * 2);
  for (const auto& [a, b] : link) {
    ends.push_back(a);
    ends.push_back(b);
  }
  std::sort(ends.begin(), ends.end());
  for (std::size_t i = 0; i + 2 < ends.size(); ++i) {
    if (ends[i] == ends[i + 2]) return false;  // degree > 2
  }
  ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
  UnionFind sets(ends.size());
  auto local = [&ends](std::uint32_t v) {
    return static_cast<std::size_t>(std::lower_bound(ends.begin(), ends.end(), v) - ends.begin());
  };
  for (const auto& [a, b] : link) sets.unite(local(a), local(b));
  for (std::size_t i = 1; i < ends.size(); ++i) {
    if (sets.find(i) != sets.find(0)) return false;
  }
  return true;
}

bool has_repeated_index(const std::array<std::uint32_t, 3>& t) {
  return t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
}

// Triangles per chunk of the area and volume sums: partial sums in chunks of a fixed size,
// added in chunk order, so the result is the same for any thread count.
constexpr std::size_t kSumChunk = std::size_t{1} << 16;

// Area, signed volume, degenerate triangles and the count of triangles with distinct indices.
void measure_triangles(const TriangleMesh& mesh, MeshCheck& check, unsigned threads) {
  const std::size_t n = mesh.positions.size();
  const std::size_t chunks = (mesh.triangles.size() + kSumChunk - 1) / kSumChunk;
  struct Partial {
    double area = 0, volume = 0;
    std::size_t degenerate = 0, valid = 0;
  };
  std::vector<Partial> partial(chunks);
  detail::run_parallel(chunks, threads, [&](std::size_t c, unsigned) {
    Partial& sum = partial[c];
    const std::size_t last = std::min(mesh.triangles.size(), (c + 1) * kSumChunk);
    for (std::size_t i = c * kSumChunk; i < last; ++i) {
      const auto& t = mesh.triangles[i];
      assert(t[0] < n && t[1] < n && t[2] < n);
      (void)n;
      if (has_repeated_index(t)) {
        ++sum.degenerate;
        continue;
      }
      ++sum.valid;
      const std::array<double, 3> a = triangle_area_vector(mesh, t);
      if (a[0] == 0.0 && a[1] == 0.0 && a[2] == 0.0) ++sum.degenerate;
      sum.area += 0.5 * std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
      // Signed volume of the tetrahedron (origin, p0, p1, p2): p0 · (p1 × p2) / 6.
      const auto& p0 = mesh.positions[t[0]];
      const auto& p1 = mesh.positions[t[1]];
      const auto& p2 = mesh.positions[t[2]];
      const double q1[3] = {p1[0], p1[1], p1[2]};
      const double q2[3] = {p2[0], p2[1], p2[2]};
      sum.volume +=
          (p0[0] * (q1[1] * q2[2] - q1[2] * q2[1]) + p0[1] * (q1[2] * q2[0] - q1[0] * q2[2]) +
           p0[2] * (q1[0] * q2[1] - q1[1] * q2[0])) /
          6.0;
    }
  });
  for (const Partial& sum : partial) {
    check.area += sum.area;
    check.volume += sum.volume;
    check.degenerate_triangles += sum.degenerate;
    check.triangles += sum.valid;
  }
}

// The triangles with distinct indices (the oracle's input).
std::vector<std::array<std::uint32_t, 3>> valid_triangles(const TriangleMesh& mesh) {
  std::vector<std::array<std::uint32_t, 3>> valid;
  valid.reserve(mesh.triangles.size());
  for (const auto& t : mesh.triangles) {
    if (!has_repeated_index(t)) valid.push_back(t);
  }
  return valid;
}

// Counts of the edges and vertices of one range of vertices.
struct LocalCounts {
  std::size_t vertices = 0, edges = 0, boundary = 0, non_manifold_edges = 0, inconsistent = 0,
              non_manifold_vertices = 0;
};

// The edges {v, x} with x > v seen from v's link. A triangle holding v and x holds one of the
// half-edges v → x (then x is the "first" of v's corner: the vertex after v) or x → v (x is
// the "second"), so the uses of the edge are the appearances of x in v's link, and its uses
// v → x those as first. Only x > v is counted, so each edge is counted once, at its lower end.
void count_edges_of_link(std::uint32_t v,
                         const std::vector<std::pair<std::uint32_t, std::uint32_t>>& link,
                         std::vector<std::pair<std::uint32_t, bool>>& ends, LocalCounts& counts) {
  ends.clear();
  for (const auto& [first, second] : link) {
    if (first > v) ends.emplace_back(first, true);
    if (second > v) ends.emplace_back(second, false);
  }
  std::sort(ends.begin(), ends.end());
  for (std::size_t i = 0; i < ends.size();) {
    std::size_t j = i, forward = 0;
    while (j < ends.size() && ends[j].first == ends[i].first) forward += ends[j++].second ? 1 : 0;
    const std::size_t uses = j - i;
    ++counts.edges;
    if (uses == 1) ++counts.boundary;
    if (uses > 2) ++counts.non_manifold_edges;
    if (forward > 1 || uses - forward > 1) ++counts.inconsistent;
    i = j;
  }
}

// Vertices per job of the per-vertex pass.
constexpr std::size_t kVertexChunk = std::size_t{1} << 15;

}  // namespace

// One pass over the triangles' corners bucketed by vertex (counting sort, O(n)), where each
// vertex's link (the edge opposite it in each of its triangles) answers both questions: is the
// vertex manifold, and how are its edges used (count_edges_of_link). It replaced a version with
// a second bucketing of the half-edges and copies of the triangles: on 1.1 M triangles the
// pipeline_bench check stage fell from 202 to 76-126 ms (2 threads) and its transient from 72
// to 17 MiB, which lowered convert's peak. The buckets hold corner numbers (3 t + k), 4 bytes
// each, not the link pairs, which are read from the triangles.
MeshCheck check_mesh(const TriangleMesh& mesh, unsigned threads) {
  MeshCheck check;
  const std::size_t n = mesh.positions.size();
  if (mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max() / 3) {
    throw std::length_error("check_mesh: more than 1.4 billion triangles");
  }
  threads = detail::resolve_threads(threads);
  measure_triangles(mesh, check, threads);

  // Components through shared vertices: a union pass that needs nothing of the rest, so with
  // more than one thread it runs beside the bucketing and the links (serial, it was a fifth
  // of the check).
  std::vector<std::uint32_t> parent(n);  // allocated here: the thread below allocates nothing
  auto unite_all = [&mesh, &parent] {
    std::iota(parent.begin(), parent.end(), 0u);
    for (const auto& t : mesh.triangles) {
      if (has_repeated_index(t)) continue;
      parent[find_root(parent, t[0])] = find_root(parent, t[1]);
      parent[find_root(parent, t[1])] = find_root(parent, t[2]);
    }
  };
  std::jthread components_thread;
  if (threads > 1) {
    components_thread = std::jthread(unite_all);
  } else {
    unite_all();
  }

  // start[v] .. start[v + 1]: the corners at v, after the scatter below.
  std::vector<std::uint32_t> start(n + 1, 0);
  for (const auto& t : mesh.triangles) {
    if (has_repeated_index(t)) continue;
    for (int k = 0; k < 3; ++k) ++start[t[k] + 1];
  }
  for (std::size_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<std::uint32_t> corners(start[n]);
  // Scatter through start[v]++ (each start moves to the next vertex's), then shift back.
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    if (has_repeated_index(t)) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      corners[start[t[k]]++] = static_cast<std::uint32_t>(3 * i) + k;
    }
  }
  for (std::size_t v = n; v > 0; --v) start[v] = start[v - 1];
  start[0] = 0;

  const std::size_t chunks = (n + kVertexChunk - 1) / kVertexChunk;
  std::vector<LocalCounts> local(chunks);
  detail::run_parallel(chunks, threads, [&](std::size_t c, unsigned) {
    LocalCounts& counts = local[c];
    std::vector<std::pair<std::uint32_t, std::uint32_t>> link;
    std::vector<std::pair<std::uint32_t, bool>> ends;
    const std::size_t last = std::min(n, (c + 1) * kVertexChunk);
    for (std::size_t v = c * kVertexChunk; v < last; ++v) {
      if (start[v] == start[v + 1]) continue;
      ++counts.vertices;
      link.clear();
      for (std::uint32_t i = start[v]; i < start[v + 1]; ++i) {
        const auto& t = mesh.triangles[corners[i] / 3];
        const std::uint32_t k = corners[i] % 3;
        link.emplace_back(t[(k + 1) % 3], t[(k + 2) % 3]);
      }
      const auto vertex = static_cast<std::uint32_t>(v);
      if (link_is_one_directed_cycle(link)) {
        // Every edge at v is then used once each way (the firsts are the seconds).
        for (const auto& entry : link) counts.edges += entry.first > vertex ? 1 : 0;
        continue;
      }
      if (!link_is_disk_or_fan_general(link)) ++counts.non_manifold_vertices;
      count_edges_of_link(vertex, link, ends, counts);
    }
  });
  for (const LocalCounts& counts : local) {
    check.vertices += counts.vertices;
    check.edges += counts.edges;
    check.boundary_edges += counts.boundary;
    check.non_manifold_edges += counts.non_manifold_edges;
    check.inconsistent_edges += counts.inconsistent;
    check.non_manifold_vertices += counts.non_manifold_vertices;
  }
  corners = {};
  if (components_thread.joinable()) components_thread.join();
  for (std::size_t v = 0; v < n; ++v) {
    if (start[v] != start[v + 1] && parent[v] == v) ++check.components;
  }

  check.euler_characteristic = static_cast<std::int64_t>(check.vertices) -
                               static_cast<std::int64_t>(check.edges) +
                               static_cast<std::int64_t>(check.triangles);
  return check;
}

MeshCheck check_after_removing_components(const TriangleMesh& mesh, const MeshCheck& before,
                                          std::size_t removed_components, unsigned threads) {
  assert(before.closed_manifold() && removed_components <= before.components);
  MeshCheck check;
  measure_triangles(mesh, check, detail::resolve_threads(threads));
  check.vertices = mesh.positions.size();
  check.edges = 3 * check.triangles / 2;
  check.components = before.components - removed_components;
  check.euler_characteristic = static_cast<std::int64_t>(check.vertices) -
                               static_cast<std::int64_t>(check.edges) +
                               static_cast<std::int64_t>(check.triangles);
  return check;
}

ExtremeAngles extreme_angles_of(const std::array<double, 3>& p, const std::array<double, 3>& q,
                                const std::array<double, 3>& r) {
  static const double cos170 = std::cos(170.0 * std::numbers::pi / 180.0);
  static const double cos1 = std::cos(std::numbers::pi / 180.0);
  const std::array<const std::array<double, 3>*, 3> corner{&p, &q, &r};
  double largest_cos = 1.0;  // cosine of the largest angle (the smallest cosine)
  double smallest_cos = -1.0;
  for (int k = 0; k < 3; ++k) {
    const auto& o = *corner[k];
    const auto& a = *corner[(k + 1) % 3];
    const auto& b = *corner[(k + 2) % 3];
    const double u[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]};
    const double v[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
    const double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    const double c =
        uu > 0 && vv > 0 ? (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / std::sqrt(uu * vv) : 1.0;
    largest_cos = std::min(largest_cos, c);
    smallest_cos = std::max(smallest_cos, c);
  }
  return {largest_cos < cos170 ? 1u : 0u, smallest_cos > cos1 ? 1u : 0u};
}

ExtremeAngles count_extreme_angles(const TriangleMesh& mesh) {
  ExtremeAngles counts;
  auto as_double = [&](std::uint32_t v) {
    const auto& p = mesh.positions[v];
    return std::array<double, 3>{p[0], p[1], p[2]};
  };
  for (const auto& t : mesh.triangles) {
    counts += extreme_angles_of(as_double(t[0]), as_double(t[1]), as_double(t[2]));
  }
  return counts;
}

namespace detail {

MeshCheck check_mesh_by_sorting(const TriangleMesh& mesh) {
  MeshCheck check;
  const std::size_t n = mesh.positions.size();
  measure_triangles(mesh, check, 1);
  const std::vector<std::array<std::uint32_t, 3>> valid = valid_triangles(mesh);

  // Edges: half-edges sorted by their undirected key, then by direction.
  struct HalfEdge {
    std::uint32_t lo, hi;
    bool forward;  // runs lo → hi
    bool operator<(const HalfEdge& o) const {
      return std::tie(lo, hi, forward) < std::tie(o.lo, o.hi, o.forward);
    }
  };
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(valid.size() * 3);
  for (const auto& t : valid) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k];
      const std::uint32_t b = t[(k + 1) % 3];
      half_edges.push_back({std::min(a, b), std::max(a, b), a < b});
    }
  }
  std::sort(half_edges.begin(), half_edges.end());
  for (std::size_t i = 0; i < half_edges.size();) {
    std::size_t j = i;
    std::size_t forward = 0;
    while (j < half_edges.size() && half_edges[j].lo == half_edges[i].lo &&
           half_edges[j].hi == half_edges[i].hi) {
      forward += half_edges[j].forward ? 1 : 0;
      ++j;
    }
    const std::size_t uses = j - i;
    ++check.edges;
    if (uses == 1) ++check.boundary_edges;
    if (uses > 2) ++check.non_manifold_edges;
    if (forward > 1 || uses - forward > 1) ++check.inconsistent_edges;
    i = j;
  }

  // Vertices: links and components.
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> links(n);
  UnionFind components(n);
  for (const auto& t : valid) {
    for (int k = 0; k < 3; ++k) links[t[k]].emplace_back(t[(k + 1) % 3], t[(k + 2) % 3]);
    components.unite(t[0], t[1]);
    components.unite(t[1], t[2]);
  }
  for (std::size_t v = 0; v < n; ++v) {
    if (links[v].empty()) continue;
    ++check.vertices;
    if (!link_is_disk_or_fan_general(links[v])) ++check.non_manifold_vertices;
    if (components.find(v) == v) ++check.components;
  }

  check.euler_characteristic = static_cast<std::int64_t>(check.vertices) -
                               static_cast<std::int64_t>(check.edges) +
                               static_cast<std::int64_t>(check.triangles);
  return check;
}

}  // namespace detail
}  // namespace typemerge::core
