// Bounded half-edge collapses (see bounded_collapse.h).
#include "core/bounded_collapse.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/triangle_grid.h"

namespace typemerge::core {

namespace {

using detail::as_point3;
using detail::Point3;
using Triangle = std::array<std::uint32_t, 3>;

// Splits of a new triangle the surface → reference test may make before it refuses: three
// levels cut a triangle's circumradius 8-fold (a fourth doubled the tests for few more
// collapses; docs/benchmarks.md).
constexpr int kLipschitzDepth = 3;
// cos 78°: a new triangle may turn at most this far from the one it replaces.
constexpr double kMinTurnCosine = 0.2079;
// Cells of the crossing grid at most: the grid's cell is raised until it fits.
constexpr double kMaxGridCells = 1 << 20;

Point3 sub(const Point3& a, const Point3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Point3& a, const Point3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Point3 mid(const Point3& a, const Point3& b) {
  return {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])};
}

// A symmetric 4×4 quadric of planes: x^T A x + 2 b·x + c.
struct Quadric {
  std::array<double, 10> q{};  // a00 a01 a02 a11 a12 a22 b0 b1 b2 c

  void add_plane(const Point3& n, double d, double weight) {
    q[0] += weight * n[0] * n[0];
    q[1] += weight * n[0] * n[1];
    q[2] += weight * n[0] * n[2];
    q[3] += weight * n[1] * n[1];
    q[4] += weight * n[1] * n[2];
    q[5] += weight * n[2] * n[2];
    q[6] += weight * n[0] * d;
    q[7] += weight * n[1] * d;
    q[8] += weight * n[2] * d;
    q[9] += weight * d * d;
  }
  Quadric& operator+=(const Quadric& o) {
    for (int k = 0; k < 10; ++k) q[k] += o.q[k];
    return *this;
  }
  double at(const Point3& p) const {
    const double x = p[0], y = p[1], z = p[2];
    return q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + q[3] * y * y + 2 * q[4] * y * z +
           q[5] * z * z + 2 * (q[6] * x + q[7] * y + q[8] * z) + q[9];
  }
};

struct Box {
  Point3 lo;
  Point3 hi;
};

bool boxes_meet(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k) {
    if (a.hi[k] < b.lo[k] || b.hi[k] < a.lo[k]) return false;
  }
  return true;
}

// Triangles in a uniform grid of cells holding lists, for a surface whose triangles change.
class FaceGrid {
 public:
  FaceGrid(const Point3& lo, const Point3& hi, double cell, double most_cells) : lo_(lo) {
    for (int a = 0; a < 3; ++a) cell = std::max(cell, (hi[a] - lo[a]) / 1024.0);
    cell = std::max(cell, 1e-9);
    auto cells_at = [&](double c) {
      double n = 1.0;
      for (int a = 0; a < 3; ++a) n *= std::floor((hi[a] - lo[a]) / c) + 1.0;
      return n;
    };
    most_cells = std::max(most_cells, 4096.0);
    while (cells_at(cell) > most_cells) cell *= 1.25;
    cell_ = cell;
    for (int a = 0; a < 3; ++a) dims_[a] = static_cast<int>((hi[a] - lo[a]) / cell_) + 1;
    cells_.resize(static_cast<std::size_t>(dims_[0]) * dims_[1] * dims_[2]);
  }

  void insert(std::uint32_t face, const Box& box) {
    for_each_cell(box, [&](std::vector<std::uint32_t>& list) { list.push_back(face); });
  }
  void erase(std::uint32_t face, const Box& box) {
    for_each_cell(box, [&](std::vector<std::uint32_t>& list) {
      auto it = std::find(list.begin(), list.end(), face);
      if (it != list.end()) {
        *it = list.back();
        list.pop_back();
      }
    });
  }
  // Calls f(face) for every listed face in a cell `box` meets (a face may come more than once).
  template <typename F>
  void visit(const Box& box, const F& f) {
    for_each_cell(box, [&](std::vector<std::uint32_t>& list) {
      for (std::uint32_t face : list) f(face);
    });
  }

 private:
  template <typename F>
  void for_each_cell(const Box& box, const F& f) {
    std::array<int, 3> c0{};
    std::array<int, 3> c1{};
    for (int a = 0; a < 3; ++a) {
      c0[a] = std::clamp(static_cast<int>(std::floor((box.lo[a] - lo_[a]) / cell_)), 0,
                         dims_[a] - 1);
      c1[a] = std::clamp(static_cast<int>(std::floor((box.hi[a] - lo_[a]) / cell_)), 0,
                         dims_[a] - 1);
    }
    for (int z = c0[2]; z <= c1[2]; ++z) {
      for (int y = c0[1]; y <= c1[1]; ++y) {
        for (int x = c0[0]; x <= c1[0]; ++x) {
          f(cells_[static_cast<std::size_t>(x) +
                   static_cast<std::size_t>(dims_[0]) *
                       (static_cast<std::size_t>(y) + static_cast<std::size_t>(dims_[1]) * z)]);
        }
      }
    }
  }

  Point3 lo_;
  double cell_ = 1.0;
  std::array<int, 3> dims_{};
  std::vector<std::vector<std::uint32_t>> cells_;
};

// A part of a reference triangle: the triangle itself (depth 0) or one of the four parts of
// the midpoint split of a part, `path` giving the part taken at each level (two bits a level).
struct Patch {
  std::uint32_t reference;
  std::uint8_t depth;
  std::uint8_t path;
};
// Levels of splitting a reference triangle that no single surface triangle covers.
constexpr int kPatchDepth = 3;

struct Candidate {
  double cost;
  std::uint32_t from;
  std::uint32_t to;
  std::uint32_t from_version;
  std::uint32_t to_version;
  bool operator>(const Candidate& o) const {
    if (cost != o.cost) return cost > o.cost;
    if (from != o.from) return from > o.from;
    return to > o.to;
  }
};

class Collapser {
 public:
  Collapser(TriangleMesh& surface, const TriangleMesh& reference, double bound)
      : s_(surface),
        ref_(reference),
        eps_(bound),
        eps2_(bound * bound),
        ref_grid_(reference),
        grid_(make_grid(surface)) {
    const std::size_t nv = s_.positions.size();
    const std::size_t nf = s_.triangles.size();
    pos_.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) pos_[v] = as_point3(s_.positions[v]);
    faces_of_.resize(nv);
    quadric_.resize(nv);
    version_.assign(nv, 0);
    held_.assign(nv, 0);
    mark_.assign(nv, 0);
    ring_mark_.assign(nv, 0);
    alive_.assign(nf, 1);
    face_mark_.assign(nf, 0);
    visited_.assign(nf, 0);
    refs_of_.resize(nf);
    ref_stamp_.assign(ref_.triangles.size(), 0);
    live_ = nf;
    for (std::uint32_t f = 0; f < nf; ++f) {
      const Triangle& t = s_.triangles[f];
      const Point3 n = triangle_area_vector(s_, t);
      const double len = std::sqrt(dot(n, n));
      if (len > 0) {
        const Point3 unit = {n[0] / len, n[1] / len, n[2] / len};
        Quadric plane;
        plane.add_plane(unit, -dot(unit, pos_[t[0]]), 0.5 * len);
        for (auto v : t) quadric_[v] += plane;
      }
      for (auto v : t) faces_of_[v].push_back(f);
      grid_.insert(f, box_of(t));
    }
  }

  // Collapses until `target` (0: while any is allowed).
  CollapseStats run(std::size_t target) {
    assign_reference();
    // Every directed edge once: on a closed oriented surface each is an edge of one triangle
    // in its winding (the reverse is its neighbour's).
    for (std::uint32_t f = 0; f < s_.triangles.size(); ++f) {
      const Triangle& t = s_.triangles[f];
      for (int k = 0; k < 3; ++k) push(t[k], t[(k + 1) % 3]);
    }
    std::make_heap(heap_.begin(), heap_.end(), std::greater<>{});
    std::size_t compact_at = 2 * heap_.size();
    while (!heap_.empty() && (target == 0 || live_ > target)) {
      std::pop_heap(heap_.begin(), heap_.end(), std::greater<>{});
      const Candidate c = heap_.back();
      heap_.pop_back();
      if (stale(c)) continue;
      if (faces_of_[c.from].empty() || held_[c.from]) continue;
      if (!collapse(c.from, c.to)) continue;
      ++stats_.collapses;
      requeue_around(c.to);
      if (heap_.size() > compact_at) {
        // Stale candidates out (a collapse outdates those around it), so the queue stays
        // within a few entries an edge.
        std::erase_if(heap_, [&](const Candidate& e) { return stale(e); });
        std::make_heap(heap_.begin(), heap_.end(), std::greater<>{});
        compact_at = std::max<std::size_t>(2 * heap_.size(), 1024);
      }
    }
    // Dead triangles out, the others in their order.
    std::size_t out = 0;
    for (std::size_t f = 0; f < s_.triangles.size(); ++f) {
      if (alive_[f]) s_.triangles[out++] = s_.triangles[f];
    }
    s_.triangles.resize(out);
    return stats_;
  }

 private:
  static FaceGrid make_grid(const TriangleMesh& mesh) {
    const BoundingBox b = bounding_box(mesh);
    double edge = 0.0;
    for (const auto& t : mesh.triangles) {
      const Point3 d = sub(as_point3(mesh.positions[t[1]]), as_point3(mesh.positions[t[0]]));
      edge += std::sqrt(dot(d, d));
    }
    edge /= static_cast<double>(std::max<std::size_t>(mesh.triangles.size(), 1));
    return FaceGrid(b.min, b.max, 2.0 * edge,
                    std::min(kMaxGridCells, 4.0 * static_cast<double>(mesh.triangles.size())));
  }

  Box box_of(const Triangle& t) const {
    Box b{pos_[t[0]], pos_[t[0]]};
    for (int k = 1; k < 3; ++k) {
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min(b.lo[a], pos_[t[k]][a]);
        b.hi[a] = std::max(b.hi[a], pos_[t[k]][a]);
      }
    }
    return b;
  }

  std::uint32_t next_query() {
    if (++query_ == 0) {
      std::fill(ref_stamp_.begin(), ref_stamp_.end(), 0);
      query_ = 1;
    }
    return query_;
  }

  std::array<Point3, 3> corners(const Patch& patch) const {
    const Triangle& rt = ref_.triangles[patch.reference];
    std::array<Point3, 3> c = {as_point3(ref_.positions[rt[0]]), as_point3(ref_.positions[rt[1]]),
                               as_point3(ref_.positions[rt[2]])};
    for (int level = 0; level < patch.depth; ++level) {
      const Point3 ab = mid(c[0], c[1]);
      const Point3 bc = mid(c[1], c[2]);
      const Point3 ca = mid(c[2], c[0]);
      switch ((patch.path >> (2 * level)) & 3) {
        case 0: c = {c[0], ab, ca}; break;
        case 1: c = {ab, c[1], bc}; break;
        case 2: c = {ca, bc, c[2]}; break;
        default: c = {ab, bc, ca}; break;
      }
    }
    return c;
  }

  static Patch part(const Patch& patch, int k) {
    return {patch.reference, static_cast<std::uint8_t>(patch.depth + 1),
            static_cast<std::uint8_t>(patch.path | (k << (2 * patch.depth)))};
  }

  // Every corner of the patch within ε of surface triangle f.
  bool covers(std::uint32_t f, const std::array<Point3, 3>& patch) const {
    const Triangle& t = s_.triangles[f];
    for (const Point3& p : patch) {
      if (detail::point_triangle_distance_squared(p, pos_[t[0]], pos_[t[1]], pos_[t[2]]) > eps2_) {
        return false;
      }
    }
    return true;
  }

  static Box box_of_points(const std::array<Point3, 3>& points, double grow) {
    Box b{points[0], points[0]};
    for (const Point3& p : points) {
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min(b.lo[a], p[a] - grow);
        b.hi[a] = std::max(b.hi[a], p[a] + grow);
      }
    }
    return b;
  }

  // Each reference triangle to one surface triangle covering it, else its parts (split up to
  // kPatchDepth levels) each to one; a part none covers is held: the vertices of every surface
  // triangle near it are held (no collapse may change those triangles, so the distance from
  // it to the surface cannot grow).
  void assign_reference() {
    const detail::TriangleGrid initial(s_);
    std::vector<std::uint32_t> stamp(s_.triangles.size(), 0);
    std::uint32_t query = 0;
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    std::vector<Patch> todo;
    for (std::uint32_t r = 0; r < ref_.triangles.size(); ++r) {
      todo.push_back({r, 0, 0});
      bool held = false;
      while (!todo.empty()) {
        const Patch patch = todo.back();
        todo.pop_back();
        const std::array<Point3, 3> c = corners(patch);
        const Point3 g = {(c[0][0] + c[1][0] + c[2][0]) / 3.0, (c[0][1] + c[1][1] + c[2][1]) / 3.0,
                          (c[0][2] + c[1][2] + c[2][2]) / 3.0};
        std::uint32_t found = kNone;
        initial.nearest_squared(g, stamp, ++query, std::numeric_limits<double>::infinity(), &found);
        if (found == kNone || !covers(found, c)) {
          found = kNone;
          grid_.visit(box_of_points(c, eps_), [&](std::uint32_t f) {
            if (found == kNone && covers(f, c)) found = f;
          });
        }
        if (found != kNone) {
          refs_of_[found].push_back(patch);
        } else if (patch.depth < kPatchDepth) {
          for (int k = 0; k < 4; ++k) todo.push_back(part(patch, k));
        } else {
          held = true;
          grid_.visit(box_of_points(c, eps_), [&](std::uint32_t f) {
            for (auto v : s_.triangles[f]) held_[v] = 1;
          });
        }
      }
      if (held) ++stats_.held_reference_triangles;
    }
  }

  // Assigns `patch`, or its parts, to triangles of candidates_ (into reassigned_).
  bool reassign(const Patch& patch) {
    const std::array<Point3, 3> c = corners(patch);
    for (std::uint32_t f : candidates_) {
      if (covers(f, c)) {
        reassigned_.push_back({f, patch});
        return true;
      }
    }
    if (patch.depth == kPatchDepth) return false;
    for (int k = 0; k < 4; ++k) {
      if (!reassign(part(patch, k))) return false;
    }
    return true;
  }

  // Every point of triangle (a, b, c) within ε of the reference (1-Lipschitz, split in four
  // where the centroid's margin does not cover the triangle).
  // `bound` is an upper bound of the distance from the centroid to the reference, when known
  // (a part's: its whole's distance plus the step between the two centroids).
  bool near_reference(const Point3& a, const Point3& b, const Point3& c, int depth,
                      double bound = std::numeric_limits<double>::infinity()) {
    const Point3 g = {(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0,
                      (a[2] + b[2] + c[2]) / 3.0};
    double radius2 = 0.0;
    for (const Point3* p : {&a, &b, &c}) radius2 = std::max(radius2, dot(sub(*p, g), sub(*p, g)));
    const double radius = std::sqrt(radius2);
    if (bound + radius <= eps_) return true;
    // One search up to ε, stopped at the first reference triangle within ε − radius (which
    // settles it; most tests look at a few cells); otherwise it gives the exact distance.
    const double margin = eps_ - radius;
    const double d2 = ref_grid_.nearest_squared(g, ref_stamp_, next_query(), eps_, nullptr,
                                                margin > 0.0 ? margin * margin : 0.0);
    if (margin > 0.0 && d2 < margin * margin) return true;
    if (d2 >= eps2_ || depth == kLipschitzDepth) return false;
    const double d = std::sqrt(d2);
    const Point3 ab = mid(a, b);
    const Point3 bc = mid(b, c);
    const Point3 ca = mid(c, a);
    auto part = [&](const Point3& p, const Point3& q, const Point3& r) {
      const Point3 h = {(p[0] + q[0] + r[0]) / 3.0, (p[1] + q[1] + r[1]) / 3.0,
                        (p[2] + q[2] + r[2]) / 3.0};
      return near_reference(p, q, r, depth + 1, d + std::sqrt(dot(sub(h, g), sub(h, g))));
    };
    return part(a, ab, ca) && part(ab, b, bc) && part(ca, bc, c) && part(ab, bc, ca);
  }

  void push_heap(std::uint32_t from, std::uint32_t to) {
    const std::size_t before = heap_.size();
    push(from, to);
    if (heap_.size() > before) std::push_heap(heap_.begin(), heap_.end(), std::greater<>{});
  }

  bool stale(const Candidate& c) const {
    return c.from_version != version_[c.from] || c.to_version != version_[c.to];
  }

  // Appends the candidate u → v (a heap only once run() has made it one).
  void push(std::uint32_t from, std::uint32_t to) {
    if (held_[from]) return;
    Quadric q = quadric_[from];
    q += quadric_[to];
    heap_.push_back({std::max(q.at(pos_[to]), 0.0), from, to, version_[from], version_[to]});
  }

  // Neighbours of v (each once; marks them in mark_ with a new stamp).
  void neighbours(std::uint32_t v, std::vector<std::uint32_t>& out) {
    out.clear();
    ++mark_stamp_;
    for (std::uint32_t f : faces_of_[v]) {
      for (auto w : s_.triangles[f]) {
        if (w != v && mark_[w] != mark_stamp_) {
          mark_[w] = mark_stamp_;
          out.push_back(w);
        }
      }
    }
  }

  void requeue_around(std::uint32_t v) {
    std::vector<std::uint32_t>& ring = ring_;
    neighbours(v, ring);
    ring.push_back(v);
    for (auto w : ring) ++version_[w];
    std::vector<std::uint32_t>& around = around_;
    // Each edge once: an edge between two ring vertices from its smaller end.
    ++ring_stamp_;
    for (auto w : ring) ring_mark_[w] = ring_stamp_;
    for (auto w : ring) {
      neighbours(w, around);
      for (auto x : around) {
        if (ring_mark_[x] == ring_stamp_ && x < w) continue;
        push_heap(w, x);
        push_heap(x, w);
      }
    }
  }

  bool collapse(std::uint32_t u, std::uint32_t v) {
    // The two triangles on uv, their third corners, the others to re-span.
    std::uint32_t on_edge[2];
    std::uint32_t opposite[2];
    int n_edge = 0;
    changed_.clear();
    for (std::uint32_t f : faces_of_[u]) {
      const Triangle& t = s_.triangles[f];
      if (t[0] == v || t[1] == v || t[2] == v) {
        if (n_edge == 2) return refuse(stats_.refused_topology);
        on_edge[n_edge] = f;
        for (auto w : t) {
          if (w != u && w != v) opposite[n_edge] = w;
        }
        ++n_edge;
      } else {
        changed_.push_back(f);
      }
    }
    if (n_edge != 2 || opposite[0] == opposite[1]) return refuse(stats_.refused_topology);
    // Link condition: the common neighbours of u and v are the two opposite corners.
    neighbours(u, ring_u_);
    neighbours(v, ring_v_);
    ++mark_stamp_;
    for (auto w : ring_u_) mark_[w] = mark_stamp_;
    int common = 0;
    for (auto w : ring_v_) {
      if (mark_[w] == mark_stamp_) {
        if (w != opposite[0] && w != opposite[1]) return refuse(stats_.refused_topology);
        ++common;
      }
    }
    if (common != 2) return refuse(stats_.refused_topology);
    if (faces_of_[opposite[0]].size() < 4 || faces_of_[opposite[1]].size() < 4) {
      return refuse(stats_.refused_topology);
    }

    // New triangles: shape, turn, distance to the reference.
    new_tri_.clear();
    for (std::uint32_t f : changed_) {
      Triangle t = s_.triangles[f];
      for (auto& w : t) {
        if (w == u) w = v;
      }
      const ExtremeAngles shape = extreme_angles_of(pos_[t[0]], pos_[t[1]], pos_[t[2]]);
      if (shape.above_170 != 0 || shape.below_1 != 0) return refuse(stats_.refused_shape);
      const Triangle& old = s_.triangles[f];
      const Point3 n_new = triangle_area_vector(s_, t);
      const Point3 n_old = triangle_area_vector(s_, old);
      if (dot(n_new, n_old) < kMinTurnCosine * std::sqrt(dot(n_new, n_new) * dot(n_old, n_old))) {
        return refuse(stats_.refused_shape);
      }
      new_tri_.push_back(t);
    }
    for (const Triangle& t : new_tri_) {
      if (!near_reference(pos_[t[0]], pos_[t[1]], pos_[t[2]], 0)) {
        return refuse(stats_.refused_distance);
      }
    }

    // Crossings, with the new triangles in place (undone when refused).
    old_tri_.clear();
    for (std::size_t k = 0; k < changed_.size(); ++k) {
      old_tri_.push_back(s_.triangles[changed_[k]]);
      s_.triangles[changed_[k]] = new_tri_[k];
    }
    auto undo = [&] {
      for (std::size_t k = 0; k < changed_.size(); ++k) s_.triangles[changed_[k]] = old_tri_[k];
      alive_[on_edge[0]] = alive_[on_edge[1]] = 1;
    };
    alive_[on_edge[0]] = alive_[on_edge[1]] = 0;
    ++face_stamp_;
    for (std::uint32_t f : changed_) face_mark_[f] = face_stamp_;
    bool crossing = false;
    for (std::size_t k = 0; k < changed_.size() && !crossing; ++k) {
      const std::uint32_t f = changed_[k];
      for (std::size_t j = k + 1; j < changed_.size() && !crossing; ++j) {
        crossing = triangles_intersect(s_, f, changed_[j]);
      }
      ++visit_stamp_;
      const Box new_box = box_of(new_tri_[k]);
      grid_.visit(new_box, [&](std::uint32_t g) {
        if (crossing || !alive_[g] || face_mark_[g] == face_stamp_) return;
        if (visited_[g] == visit_stamp_) return;
        visited_[g] = visit_stamp_;
        if (!boxes_meet(new_box, box_of(s_.triangles[g]))) return;
        crossing = triangles_intersect(s_, f, g);
      });
    }
    if (crossing) {
      undo();
      return refuse(stats_.refused_crossing);
    }

    // Reference triangles of every triangle changed or gone, to a triangle around v.
    candidates_.assign(changed_.begin(), changed_.end());
    for (std::uint32_t f : faces_of_[v]) {
      if (f != on_edge[0] && f != on_edge[1]) candidates_.push_back(f);
    }
    reassigned_.clear();
    auto reassign_all = [&](std::uint32_t from) {
      for (const Patch& patch : refs_of_[from]) {
        if (!reassign(patch)) return false;
      }
      return true;
    };
    bool covered = reassign_all(on_edge[0]) && reassign_all(on_edge[1]);
    for (std::size_t k = 0; k < changed_.size() && covered; ++k) covered = reassign_all(changed_[k]);
    if (!covered) {
      undo();
      return refuse(stats_.refused_distance);
    }

    // Commit.
    for (std::size_t k = 0; k < changed_.size(); ++k) {
      grid_.erase(changed_[k], box_of(old_tri_[k]));
      grid_.insert(changed_[k], box_of(new_tri_[k]));
    }
    for (int e = 0; e < 2; ++e) {
      grid_.erase(on_edge[e], box_of(s_.triangles[on_edge[e]]));
      refs_of_[on_edge[e]].clear();
      auto drop = [&](std::uint32_t w) {
        auto& list = faces_of_[w];
        list.erase(std::find(list.begin(), list.end(), on_edge[e]));
      };
      drop(v);
      drop(opposite[e]);
    }
    for (std::uint32_t f : changed_) {
      refs_of_[f].clear();
      faces_of_[v].push_back(f);
    }
    for (const auto& [to, patch] : reassigned_) refs_of_[to].push_back(patch);
    faces_of_[u].clear();
    quadric_[v] += quadric_[u];
    ++version_[u];
    live_ -= 2;
    return true;
  }

  static bool refuse(std::size_t& counter) {
    ++counter;
    return false;
  }

  TriangleMesh& s_;
  const TriangleMesh& ref_;
  const double eps_;
  const double eps2_;
  detail::TriangleGrid ref_grid_;
  FaceGrid grid_;
  std::vector<Point3> pos_;
  std::vector<std::vector<std::uint32_t>> faces_of_;
  std::vector<Quadric> quadric_;
  std::vector<std::uint32_t> version_;
  std::vector<std::uint8_t> held_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t mark_stamp_ = 0;
  std::vector<std::uint32_t> ring_mark_;
  std::uint32_t ring_stamp_ = 0;
  std::vector<std::uint8_t> alive_;
  std::vector<std::uint32_t> face_mark_;
  std::uint32_t face_stamp_ = 0;
  std::vector<std::uint32_t> visited_;
  std::uint32_t visit_stamp_ = 0;
  std::vector<std::vector<Patch>> refs_of_;
  std::vector<std::uint32_t> ref_stamp_;
  std::uint32_t query_ = 0;
  std::size_t live_ = 0;
  CollapseStats stats_;
  std::vector<Candidate> heap_;  // candidates, smallest cost on top (std::greater)
  // Scratch of collapse().
  std::vector<std::uint32_t> changed_;
  std::vector<Triangle> new_tri_;
  std::vector<Triangle> old_tri_;
  std::vector<std::uint32_t> ring_u_;
  std::vector<std::uint32_t> ring_;
  std::vector<std::uint32_t> around_;
  std::vector<std::uint32_t> ring_v_;
  std::vector<std::uint32_t> candidates_;
  std::vector<std::pair<std::uint32_t, Patch>> reassigned_;
};

}  // namespace

CollapseStats collapse_within_bound(TriangleMesh& surface, const TriangleMesh& reference,
                                    const CollapseOptions& options) {
  if (!(options.bound > 0.0) || !std::isfinite(options.bound)) {
    throw std::invalid_argument("collapse_within_bound: the bound must be finite and > 0");
  }
  if (surface.triangles.empty() || reference.triangles.empty()) return {};
  Collapser collapser(surface, reference, options.bound);
  return collapser.run(options.target);
}


}  // namespace typemerge::core
