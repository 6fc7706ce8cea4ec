// Bounded half-edge collapses (see bounded_collapse.h).
#include "core/bounded_collapse.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <cstdint>
#include <functional>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/plane_side.h"
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
// The overlay proof's slab: the reference within this many ε of a new triangle's plane is
// what it projects onto the triangle.
constexpr double kOverlaySlab = 1.25;
// Halvings of a new triangle the corner test may make (one search each) before the centroid
// test takes over.
constexpr int kBisectDepth = 2;
// Their parts' cover radius is about half the triangle's: beyond this many ε, no halving proves
// it and the overlay proof is tried before them.
constexpr double kHalvingsReach = 2.0;
// cos 78°: a new triangle may turn at most this far from the one it replaces.
constexpr double kMinTurnCosine = 0.2079;
// The crossing grid's cell, in mean edges of the live triangles.
constexpr double kCellEdges = 4.0;
// Placement's regularisation: the quadric's matrix plus this share of its trace times the
// identity, so that directions the planes leave free do not move the point.
constexpr double kRegularization = 1e-3;
// Placement leaves the kept vertex where it is when its point is this share of ε or less
// away (a move that small changes every triangle around it for nothing measurable).
constexpr double kStayShare = 0.01;

Point3 sub(const Point3& a, const Point3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Point3& a, const Point3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Point3 mid(const Point3& a, const Point3& b) {
  return {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])};
}
Point3 cross(const Point3& a, const Point3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// A point in a triangle's frame: x, y in its plane, h along its unit normal.
struct LocalPoint {
  double x;
  double y;
  double h;
};

// A convex polygon of the overlay proof (a reference triangle cut by at most five planes has
// at most eight corners; rounding may add a few, `overflow` when it would add too many). Only
// the first n corners are read.
struct LocalPolygon {
  std::array<LocalPoint, 16> p;
  int n = 0;
  bool overflow = false;
};

// Into `out`, the part of `in` where side(point) >= 0 (side affine), in the same orientation.
template <typename Side>
void clip(const LocalPolygon& in, LocalPolygon& out, const Side& side) {
  out.n = 0;
  out.overflow = in.overflow;
  if (in.n == 0) return;
  const LocalPoint* a = &in.p[in.n - 1];
  double sa = side(*a);
  for (int i = 0; i < in.n; ++i) {
    const LocalPoint& b = in.p[i];
    const double sb = side(b);
    if (out.n + 2 > static_cast<int>(out.p.size())) {
      out.overflow = true;
      return;
    }
    if ((sa >= 0.0) != (sb >= 0.0)) {
      const double t = sa / (sa - sb);
      out.p[out.n++] = {a->x + t * (b.x - a->x), a->y + t * (b.y - a->y), a->h + t * (b.h - a->h)};
    }
    if (sb >= 0.0) out.p[out.n++] = b;
    a = &b;
    sa = sb;
  }
}

// Twice the signed area of the polygon's projection on its plane (x, y).
double twice_signed_area(const LocalPolygon& poly) {
  double sum = 0.0;
  for (int i = 0; i < poly.n; ++i) {
    const LocalPoint& a = poly.p[i];
    const LocalPoint& b = poly.p[(i + 1) % poly.n];
    sum += a.x * b.y - a.y * b.x;
  }
  return sum;
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

// The largest distance from a point of triangle abc to its nearest corner: the circumradius
// when no angle is obtuse (the circumcentre is in the triangle); otherwise the Voronoi cells of
// the corners meet the longest side at the points equidistant from its ends and the obtuse
// corner, the farthest points (the distance to a corner is convex, its maximum over a cell at
// a vertex of the cell). Infinite for a degenerate triangle.
double cover_radius(const Point3& a, const Point3& b, const Point3& c) {
  const double la2 = dot(sub(b, c), sub(b, c));  // opposite a
  const double lb2 = dot(sub(c, a), sub(c, a));  // opposite b
  const double lc2 = dot(sub(a, b), sub(a, b));  // opposite c
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // With the obtuse corner at C (its opposite side AB the longest), the point of AB as far from
  // A as from C is |AC|² |AB| / (|AC|² + |AB|² − |BC|²) from A, likewise for B.
  auto obtuse = [&](double opp2, double s12, double s22) {  // opp2 > s12 + s22
    const double opp = std::sqrt(opp2);
    const double d1 = s12 + opp2 - s22;
    const double d2 = s22 + opp2 - s12;
    if (!(d1 > 0.0) || !(d2 > 0.0)) return kInf;
    return std::max(s12 * opp / d1, s22 * opp / d2);
  };
  if (la2 > lb2 + lc2) return obtuse(la2, lb2, lc2);
  if (lb2 > lc2 + la2) return obtuse(lb2, lc2, la2);
  if (lc2 > la2 + lb2) return obtuse(lc2, la2, lb2);
  const Point3 ab = sub(b, a);
  const Point3 ac = sub(c, a);
  const Point3 n = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2],
                    ab[0] * ac[1] - ab[1] * ac[0]};
  const double twice_area = std::sqrt(dot(n, n));
  if (!(twice_area > 0.0)) return kInf;
  return std::sqrt(la2 * lb2 * lc2) / (2.0 * twice_area);  // abc / (4 area)
}

// Triangles in a hashed uniform grid, for a surface whose triangles change: the cells (`cell`
// wide) a triangle's box meets list it with its box, the cells hashed into a table of lists (a
// surface fills few of its bounding box's cells; cells sharing a list only add entries, which
// the box test rejects). Boxes in float: the corners are floats, so they are exact.
class FaceGrid {
 public:
  FaceGrid(const Point3& lo, const Point3& hi, double cell, std::size_t lists) : lo_(lo) {
    std::size_t n = 4096;
    while (n < lists) n *= 2;
    mask_ = n - 1;
    lists_.resize(n);
    // At most 16 cells a list over the bounding box (box queries are clipped to it), so a
    // stray large triangle visits a bounded number of cells.
    cell = std::max(cell, 1e-9);
    auto cells_at = [&](double c) {
      double cells = 1.0;
      for (int a = 0; a < 3; ++a) cells *= std::floor((hi[a] - lo[a]) / c) + 1.0;
      return cells;
    };
    while (cells_at(cell) > 16.0 * static_cast<double>(n)) cell *= 1.25;
    cell_ = cell;
    for (int a = 0; a < 3; ++a) dims_[a] = static_cast<std::int64_t>((hi[a] - lo[a]) / cell_) + 1;
  }

  void insert(std::uint32_t face, const Box& box) {
    Entry entry{face, {}, {}};
    for (int a = 0; a < 3; ++a) {
      entry.lo[a] = static_cast<float>(box.lo[a]);
      entry.hi[a] = static_cast<float>(box.hi[a]);
    }
    for_each_cell(box, [&](std::vector<Entry>& list) { list.push_back(entry); });
  }
  void erase(std::uint32_t face, const Box& box) {
    for_each_cell(box, [&](std::vector<Entry>& list) {
      auto it = std::find_if(list.begin(), list.end(), [&](const Entry& e) { return e.face == face; });
      if (it != list.end()) {
        *it = list.back();
        list.pop_back();
      }
    });
  }
  // Calls f(face) for every face entered with a box that meets `box` (a face may come more than
  // once).
  // With f(face, its box) when f takes two arguments.
  template <typename F>
  void visit(const Box& box, const F& f) {
    for_each_cell(box, [&](std::vector<Entry>& list) {
      for (const Entry& e : list) {
        if (e.hi[0] < box.lo[0] || box.hi[0] < e.lo[0] || e.hi[1] < box.lo[1] ||
            box.hi[1] < e.lo[1] || e.hi[2] < box.lo[2] || box.hi[2] < e.lo[2]) {
          continue;
        }
        if constexpr (std::is_invocable_v<F, std::uint32_t, const Box&>) {
          const Box entry_box{{e.lo[0], e.lo[1], e.lo[2]}, {e.hi[0], e.hi[1], e.hi[2]}};
          f(e.face, entry_box);
        } else {
          f(e.face);
        }
      }
    });
  }

 private:
  template <typename F>
  void for_each_cell(const Box& box, const F& f) {
    std::array<std::int64_t, 3> c0{};
    std::array<std::int64_t, 3> c1{};
    for (int a = 0; a < 3; ++a) {
      c0[a] = std::clamp(static_cast<std::int64_t>(std::floor((box.lo[a] - lo_[a]) / cell_)),
                         std::int64_t{0}, dims_[a] - 1);
      c1[a] = std::clamp(static_cast<std::int64_t>(std::floor((box.hi[a] - lo_[a]) / cell_)),
                         std::int64_t{0}, dims_[a] - 1);
    }
    for (std::int64_t z = c0[2]; z <= c1[2]; ++z) {
      for (std::int64_t y = c0[1]; y <= c1[1]; ++y) {
        for (std::int64_t x = c0[0]; x <= c1[0]; ++x) {
          const auto key = static_cast<std::uint64_t>(x) * 73856093u ^
                           static_cast<std::uint64_t>(y) * 19349663u ^
                           static_cast<std::uint64_t>(z) * 83492791u;
          f(lists_[static_cast<std::size_t>(key & mask_)]);
        }
      }
    }
  }

  Point3 lo_;
  double cell_ = 1.0;
  std::array<std::int64_t, 3> dims_{};
  struct Entry {
    std::uint32_t face;
    std::array<float, 3> lo;
    std::array<float, 3> hi;
  };
  std::uint64_t mask_ = 0;
  std::vector<std::vector<Entry>> lists_;
};

constexpr std::uint32_t kNoFace = std::numeric_limits<std::uint32_t>::max();

// A part of a reference triangle: the triangle itself (depth 0) or one of the four parts of
// the midpoint split of a part, `path` giving the part taken at each level (two bits a level).
struct Patch {
  std::uint32_t reference;
  std::uint8_t depth;
  std::uint8_t path;
  std::uint16_t epoch = 0;  // a union patch's proof (kUnion): current while it equals the
                            // reference triangle's epoch
};
// A whole reference triangle proved within ε of several surface triangles together (the
// overlay proof against the surface): listed with each of those whose pieces prove it.
constexpr std::uint8_t kUnion = 0xFF;
// Levels of splitting a reference triangle that no single surface triangle covers.
constexpr int kPatchDepth = 3;

enum class Proof { yes, no, unknown };

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

// A 4-ary min-heap of candidates in a vector (half the levels of a binary heap, the four
// children of an entry side by side: fewer cache misses on a queue of a million entries).
// The order is total (cost, from, to), so it pops what std::pop_heap would.
class CandidateHeap {
 public:
  bool empty() const { return items_.empty(); }
  std::size_t size() const { return items_.size(); }
  // Appends without ordering; make() orders.
  void append(const Candidate& c) { items_.push_back(c); }
  void make() {
    for (std::size_t i = items_.size() / 4 + 1; i-- > 0;) sift_down(i);
  }
  void push(const Candidate& c) {
    items_.push_back(c);
    std::size_t i = items_.size() - 1;
    while (i > 0) {
      const std::size_t parent = (i - 1) / 4;
      if (!(items_[parent] > c)) break;
      items_[i] = items_[parent];
      i = parent;
    }
    items_[i] = c;
  }
  Candidate pop() {
    const Candidate top = items_.front();
    items_.front() = items_.back();
    items_.pop_back();
    if (!items_.empty()) sift_down(0);
    return top;
  }
  template <typename P>
  void erase_if(const P& p) {
    std::erase_if(items_, p);
    make();
  }

 private:
  void sift_down(std::size_t i) {
    const std::size_t n = items_.size();
    if (i >= n) return;
    const Candidate c = items_[i];
    for (;;) {
      const std::size_t first = 4 * i + 1;
      if (first >= n) break;
      std::size_t best = first;
      const std::size_t last = std::min(first + 4, n);
      for (std::size_t k = first + 1; k < last; ++k) {
        if (items_[best] > items_[k]) best = k;
      }
      if (!(c > items_[best])) break;
      items_[i] = items_[best];
      i = best;
    }
    items_[i] = c;
  }

  std::vector<Candidate> items_;
};

class Collapser {
 public:
  Collapser(TriangleMesh& surface, const TriangleMesh& reference, const CollapseOptions& options)
      : s_(surface),
        ref_(reference),
        eps_(options.bound),
        eps2_(options.bound * options.bound),
        move_(options.move_vertices),
        geometry_(options.geometry),
        frame_(options.frame),
        ref_grid_(reference),
        grid_(make_grid(surface)) {
    if (geometry_ != nullptr) {
      // The inverse of the index → patient map's linear part.
      const double det = geometry_->determinant();
      inverse_ = geometry_->cofactor_rows();
      for (auto& row : inverse_) {
        for (double& x : row) x /= det;
      }
    }
    const std::size_t nv = s_.positions.size();
    const std::size_t nf = s_.triangles.size();
    pos_.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) pos_[v] = as_point3(s_.positions[v]);
    faces_of_.resize(nv);
    quadric_.resize(nv);
    version_.assign(nv, 0);
    held_.assign(nv, 0);
    mark_.assign(nv, 0);
    alive_.assign(nf, 1);
    face_mark_.assign(nf, 0);
    visited_.assign(nf, 0);
    refs_of_.resize(nf);
    refused_from_.resize(nv);
    ref_stamp_.assign(ref_.triangles.size(), 0);
    epoch_.assign(ref_.triangles.size(), 0);
    redone_.assign(ref_.triangles.size(), 0);
    vertex_distance_.assign(nv, -1.0);
    mark_reference_vertices();
    live_ = nf;
    grid_live_ = nf;
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
    hold_border();
    // The overlay proof needs a closed reference; an open surface's border is the reference's.
    overlay_ = std::find(held_.begin(), held_.end(), 1) == held_.end();
    // Parts split kPatchDepth levels are an eighth of a reference triangle: where ε is smaller
    // still, a part across an edge of the surface is seldom within ε of one triangle, so the
    // overlay proof is tried before any split (it lists a triangle several times, so only then).
    union_first_ = overlay_ && eps_ * (1 << kPatchDepth) < ref_grid_.mean_edge();
  }

  // A surface vertex at exactly the position of a corner of a reference triangle is at
  // distance 0 from the reference, as every vertex of a type-merged surface is (marching
  // cubes' vertices, at the same floats): known without the search vertex_distance makes,
  // from the corners' positions sorted (their bits, compared as integers).
  void mark_reference_vertices() {
    using Key = std::array<std::uint32_t, 3>;
    auto key = [](const std::array<float, 3>& p) {
      Key k{};
      std::memcpy(k.data(), p.data(), sizeof k);
      return k;
    };
    std::vector<Key> corners;
    corners.reserve(ref_.positions.size());
    std::vector<std::uint8_t> used(ref_.positions.size(), 0);
    for (const Triangle& t : ref_.triangles) {
      for (std::uint32_t v : t) {
        if (used[v] == 0) corners.push_back(key(ref_.positions[v]));
        used[v] = 1;
      }
    }
    std::sort(corners.begin(), corners.end());
    for (std::size_t w = 0; w < s_.positions.size(); ++w) {
      if (std::binary_search(corners.begin(), corners.end(), key(s_.positions[w]))) {
        vertex_distance_[w] = 0.0;
      }
    }
  }

  // The ends of every edge in one triangle only (a surface left open where it meets the
  // volume's border) are held: the border stays as it is, and every vertex collapsed away has
  // a closed fan of triangles around it.
  void hold_border() {
    for (std::uint32_t v = 0; v < faces_of_.size(); ++v) {
      for (std::uint32_t f : faces_of_[v]) {
        for (std::uint32_t w : s_.triangles[f]) {
          if (w == v) continue;
          const auto on_vw = std::count_if(
              faces_of_[v].begin(), faces_of_[v].end(), [&](std::uint32_t g) {
                const Triangle& t = s_.triangles[g];
                return t[0] == w || t[1] == w || t[2] == w;
              });
          if (on_vw == 1) held_[v] = held_[w] = 1;
        }
      }
    }
  }

  // Collapses until `target` (0: while any is allowed), passing over candidates whose
  // quadric estimate exceeds `local_rms` (0: none).
  CollapseStats run(std::size_t target, double local_rms) {
    local_rms2_ = local_rms * local_rms;
    assign_reference();
    // Every directed edge once: on a closed oriented surface each is an edge of one triangle
    // in its winding (the reverse is its neighbour's).
    for (std::uint32_t f = 0; f < s_.triangles.size(); ++f) {
      const Triangle& t = s_.triangles[f];
      for (int k = 0; k < 3; ++k) push(t[k], t[(k + 1) % 3]);
    }
    heap_.make();
    auto compact_after = [](std::size_t size) {
      return std::max<std::size_t>(size + size / 10, 1024);
    };
    std::size_t compact_at = compact_after(heap_.size());
    while (!heap_.empty() && (target == 0 || live_ > target)) {
      const Candidate c = heap_.pop();
      if (stale(c)) continue;
      if (faces_of_[c.from].empty() || held_[c.from]) continue;
      if (!collapse(c.from, c.to)) {
        refused_from_[c.from].push_back(c.to);
        continue;
      }
      ++stats_.collapses;
      if (3 * live_ < 2 * grid_live_) rebuild_grid();
      requeue_around(c.to);
      if (heap_.size() > compact_at) {
        // Stale candidates out (a collapse outdates those around it) once the queue has grown
        // by a tenth: left in, they are most of what is popped (86 % on the abdomen's bone at
        // 10 %), each a sift through the heap, and the pass over it costs less. Only stale
        // entries go, and the order is total, so the collapses are the same.
        heap_.erase_if([&](const Candidate& e) { return stale(e); });
        compact_at = compact_after(heap_.size());
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
    return FaceGrid(b.min, b.max, kCellEdges * edge, 2 * mesh.triangles.size());
  }

  // The crossing grid anew for the live triangles, its cells two of their mean edges: as
  // collapses make triangles larger, a grid sized for the first ones lists each in more and
  // more cells (the crossing test then visits each candidate many times).
  void rebuild_grid() {
    Point3 lo = pos_[s_.triangles[0][0]];
    Point3 hi = lo;
    double edge = 0.0;
    for (std::uint32_t f = 0; f < s_.triangles.size(); ++f) {
      if (!alive_[f]) continue;
      const Triangle& t = s_.triangles[f];
      for (auto v : t) {
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], pos_[v][a]);
          hi[a] = std::max(hi[a], pos_[v][a]);
        }
      }
      const Point3 d = sub(pos_[t[1]], pos_[t[0]]);
      edge += std::sqrt(dot(d, d));
    }
    edge /= static_cast<double>(std::max<std::size_t>(live_, 1));
    grid_ = FaceGrid(lo, hi, kCellEdges * edge, 2 * live_);
    for (std::uint32_t f = 0; f < s_.triangles.size(); ++f) {
      if (alive_[f]) grid_.insert(f, box_of(s_.triangles[f]));
    }
    grid_live_ = live_;
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
  // kPatchDepth levels) each to one; where a part none covers, the whole triangle by the
  // overlay proof (union_covers), else that part is held: the vertices of every surface
  // triangle near it are held (no collapse may change those triangles, so the distance from
  // it to the surface cannot grow).
  void assign_reference() {
    const detail::TriangleGrid initial(s_);
    std::vector<std::uint32_t> stamp(s_.triangles.size(), 0);
    std::uint32_t query = 0;
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    std::vector<Patch> todo;
    std::vector<std::pair<std::uint32_t, Patch>> listed;  // r's parts, to their triangles
    std::vector<Patch> uncovered;                          // r's parts none covers
    std::uint32_t last = kNone;
    for (std::uint32_t r = 0; r < ref_.triangles.size(); ++r) {
      todo.push_back({r, 0, 0});
      listed.clear();
      uncovered.clear();
      while (!todo.empty()) {
        const Patch patch = todo.back();
        todo.pop_back();
        const std::array<Point3, 3> c = corners(patch);
        const Point3 g = {(c[0][0] + c[1][0] + c[2][0]) / 3.0, (c[0][1] + c[1][1] + c[2][1]) / 3.0,
                          (c[0][2] + c[1][2] + c[2][2]) / 3.0};
        // Consecutive reference triangles are neighbours, often covered by the same triangle.
        if (last != kNone && covers(last, c)) {
          listed.push_back({last, patch});
          continue;
        }
        std::uint32_t found = kNone;
        initial.nearest_squared(g, stamp, ++query, std::numeric_limits<double>::infinity(), &found);
        if (found == kNone || !covers(found, c)) {
          found = kNone;
          grid_.visit(box_of_points(c, eps_), [&](std::uint32_t f) {
            if (found == kNone && covers(f, c)) found = f;
          });
        }
        if (found != kNone) {
          listed.push_back({found, patch});
          last = found;
        } else if (patch.depth == 0 && union_first_ && union_covers(r, epoch_[r])) {
          listed.assign(reassigned_.begin(), reassigned_.end());
          reassigned_.clear();
        } else if (patch.depth < kPatchDepth) {
          for (int k = 0; k < 4; ++k) todo.push_back(part(patch, k));
        } else {
          uncovered.push_back(patch);
        }
      }
      // A part none covers: the whole triangle by the overlay proof, else the part is held.
      if (!uncovered.empty() && overlay_ && !union_first_ && union_covers(r, epoch_[r])) {
        listed.assign(reassigned_.begin(), reassigned_.end());
        reassigned_.clear();
        uncovered.clear();
      }
      for (const auto& [to, patch] : listed) refs_of_[to].push_back(patch);
      for (const Patch& patch : uncovered) {
        grid_.visit(box_of_points(corners(patch), eps_), [&](std::uint32_t f) {
          for (auto v : s_.triangles[f]) held_[v] = 1;
        });
      }
      if (!uncovered.empty()) ++stats_.held_reference_triangles;
    }
  }

  // Reference triangle r within ε of the live surface as it is (its triangles changed by a
  // collapse being tried included, as in s_.triangles; their grid boxes may be old, so they
  // are listed from changed_), by the overlay proof: its registrations, with the epoch
  // `epoch`, into reassigned_.
  bool union_covers(std::uint32_t r, std::uint16_t epoch) {
    const std::array<Point3, 3> c = corners(Patch{r, 0, 0});
    auto triangle = [&](std::uint32_t f) {
      const Triangle& t = s_.triangles[f];
      return std::array<Point3, 3>{pos_[t[0]], pos_[t[1]], pos_[t[2]]};
    };
    auto near_surface_triangles = [&](const Point3& lo, const Point3& hi, const auto& f) {
      ++visit_stamp_;
      for (std::uint32_t g : changed_) {
        visited_[g] = visit_stamp_;
        f(triangle(g), g);
      }
      grid_.visit(Box{lo, hi}, [&](std::uint32_t g) {
        if (!alive_[g] || visited_[g] == visit_stamp_) return;
        visited_[g] = visit_stamp_;
        f(triangle(g), g);
      });
    };
    const std::size_t mark = reassigned_.size();
    const Patch patch{r, kUnion, 0, epoch};
    const bool proved = overlay_proves(c[0], c[1], c[2], near_surface_triangles,
                                       [&](std::uint32_t f) { reassigned_.push_back({f, patch}); });
    if (proved) {
      ++stats_.reference_overlay_proofs;
    } else {
      reassigned_.resize(mark);
    }
    return proved;
  }

  // Assigns `patch`, or its parts, to triangles of candidates_ (into reassigned_), `hint`
  // (the last triangle that covered one) tried first.
  // Reference triangle r is proved again by the collapse being tried: once it is made, r's
  // earlier union listings are old.
  void renew(std::uint32_t r) {
    if (redone_[r] == attempt_) return;
    redone_[r] = attempt_;
    renewed_.push_back(r);
  }

  // A union patch is proved again, once a collapse, as a whole reference triangle; the one
  // listing of an old proof is passed over.
  bool reassign(const Patch& patch, std::uint32_t& hint) {
    const std::uint32_t r = patch.reference;
    if (patch.depth == kUnion) {
      if (patch.epoch != epoch_[r] || redone_[r] == attempt_) return true;
      renew(r);
      return reassign(Patch{r, 0, 0}, hint);
    }
    const std::array<Point3, 3> c = corners(patch);
    if (hint != kNoFace && covers(hint, c)) {
      reassigned_.push_back({hint, patch});
      return true;
    }
    for (std::uint32_t f : candidates_) {
      if (f != hint && covers(f, c)) {
        reassigned_.push_back({f, patch});
        hint = f;
        return true;
      }
    }
    if (patch.depth == 0 && union_first_) {
      renew(r);
      if (union_covers(r, static_cast<std::uint16_t>(epoch_[r] + 1))) return true;
    }
    if (patch.depth == kPatchDepth) return false;
    const std::size_t mark = reassigned_.size();
    bool parts = true;
    for (int k = 0; k < 4 && parts; ++k) parts = reassign(part(patch, k), hint);
    if (parts || patch.depth != 0 || !overlay_ || union_first_) return parts;
    // A whole triangle its parts cannot cover: the overlay proof, listed only where needed
    // (a union listing takes several entries).
    reassigned_.resize(mark);
    renew(r);
    return union_covers(r, static_cast<std::uint16_t>(epoch_[r] + 1));
  }

  static Point3 centroid(const Point3& a, const Point3& b, const Point3& c) {
    return {(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0, (a[2] + b[2] + c[2]) / 3.0};
  }
  static double centroid_radius(const Point3& a, const Point3& b, const Point3& c,
                                const Point3& g) {
    double radius2 = 0.0;
    for (const Point3* p : {&a, &b, &c}) radius2 = std::max(radius2, dot(sub(*p, g), sub(*p, g)));
    return std::sqrt(radius2);
  }

  // The centroid test at g (radius: the farthest corner from g): Proof::yes when a reference
  // triangle lies within ε − radius of g, Proof::no when none lies within ε, else unknown with
  // the exact distance in *distance. One search up to ε, stopped at the first reference
  // triangle within ε − radius (most tests look at a few cells).
  Proof centroid_test(const Point3& g, double radius, double* distance) {
    const double margin = eps_ - radius;
    const double d2 = ref_grid_.nearest_squared(g, ref_stamp_, next_query(), eps_, nullptr,
                                                margin > 0.0 ? margin * margin : 0.0);
    if (margin > 0.0 && d2 < margin * margin) return Proof::yes;
    if (d2 >= eps2_) return Proof::no;
    *distance = std::sqrt(d2);
    return Proof::unknown;
  }

  // Every point of triangle (a, b, c) within ε of the reference (1-Lipschitz, split in four
  // where the centroid's margin does not cover the triangle). `bound` is an upper bound of the
  // distance from the centroid to the reference, when known (a part's: its whole's distance
  // plus the step between the two centroids); with `exact`, it is that distance, searched.
  // The four parts' centroids are tested before any part is split further, so a part out of
  // reach refuses the triangle before the others are proved.
  bool near_reference(const Point3& a, const Point3& b, const Point3& c, int depth,
                      double bound = std::numeric_limits<double>::infinity(),
                      bool exact = false) {
    const Point3 g = centroid(a, b, c);
    const double radius = centroid_radius(a, b, c, g);
    if (bound + radius <= eps_) return true;
    double d = bound;
    if (!exact) {
      const Proof proof = centroid_test(g, radius, &d);
      if (proof != Proof::unknown) return proof == Proof::yes;
    }
    if (depth == kLipschitzDepth) return false;
    const Point3 ab = mid(a, b);
    const Point3 bc = mid(b, c);
    const Point3 ca = mid(c, a);
    const std::array<std::array<Point3, 3>, 4> parts = {{{a, ab, ca}, {ab, b, bc}, {ca, bc, c},
                                                         {ab, bc, ca}}};
    std::array<double, 4> open{};  // a part's exact centroid distance; < 0: proved
    for (std::size_t k = 0; k < 4; ++k) {
      const auto& [p, q, r] = parts[k];
      const Point3 h = centroid(p, q, r);
      const double part_radius = centroid_radius(p, q, r, h);
      open[k] = -1.0;
      if (d + std::sqrt(dot(sub(h, g), sub(h, g))) + part_radius <= eps_) continue;
      const Proof proof = centroid_test(h, part_radius, &open[k]);
      if (proof == Proof::no) return false;
      if (proof == Proof::yes) open[k] = -1.0;
    }
    for (std::size_t k = 0; k < 4; ++k) {
      if (open[k] < 0.0) continue;
      const auto& [p, q, r] = parts[k];
      if (!near_reference(p, q, r, depth + 1, open[k], true)) return false;
    }
    return true;
  }

  // An upper bound of the distance from surface vertex w to the reference (infinite when it is
  // ε or more): 0 at a reference corner (mark_reference_vertices), else searched once a vertex
  // and again when it moves; the search stops at the first reference triangle through w (a
  // distance of 0, the nearest).
  double vertex_distance(std::uint32_t w) {
    double& d = vertex_distance_[w];
    if (d < 0.0) {
      const double d2 = ref_grid_.nearest_squared(pos_[w], ref_stamp_, next_query(), eps_,
                                                  nullptr, std::numeric_limits<double>::min());
      d = d2 < eps2_ ? std::sqrt(d2) : std::numeric_limits<double>::infinity();
    }
    return d;
  }

  // Every point of triangle abc within ε of the reference by its corners' distances
  // (upper bounds, `d`) and its cover radius, halving it at its longest side's midpoint
  // (searched) where they do not suffice, down to kBisectDepth levels.
  // Proof::no when a searched midpoint lies ε or more from the reference.
  Proof corners_prove(const Point3& a, const Point3& b, const Point3& c,
                      const std::array<double, 3>& d, int depth) {
    if (std::max({d[0], d[1], d[2]}) + cover_radius(a, b, c) * (1.0 + 1e-12) <= eps_) {
      return Proof::yes;
    }
    if (depth == kBisectDepth) return Proof::unknown;
    const double la2 = dot(sub(b, c), sub(b, c));
    const double lb2 = dot(sub(c, a), sub(c, a));
    const double lc2 = dot(sub(a, b), sub(a, b));
    // Rotated so that the longest side is bc (strictly longer than bc: no rotation repeats).
    if (lb2 > la2 && lb2 >= lc2) return corners_prove(b, c, a, {d[1], d[2], d[0]}, depth);
    if (lc2 > la2 && lc2 > lb2) return corners_prove(c, a, b, {d[2], d[0], d[1]}, depth);
    const Point3 m = mid(b, c);
    // An upper bound is enough: the search stops at the first triangle within ε / 4.
    const double d2 = ref_grid_.nearest_squared(m, ref_stamp_, next_query(), eps_, nullptr,
                                                eps2_ / 16.0);
    if (d2 >= eps2_) return Proof::no;  // none below ε/4 found: d2 is the exact distance
    const double dm = std::sqrt(d2);
    const Proof left = corners_prove(a, b, m, {d[0], d[1], dm}, depth + 1);
    if (left == Proof::no) return Proof::no;
    const Proof right = corners_prove(a, m, c, {d[0], dm, d[2]}, depth + 1);
    if (right == Proof::no) return Proof::no;
    return left == Proof::yes && right == Proof::yes ? Proof::yes : Proof::unknown;
  }

  // Every point of triangle abc within ε of a closed mesh M, by M beneath it (the overlay
  // proof). `each_near(lo, hi, f)` calls f(corners, id) for every triangle of M meeting the
  // box [lo, hi] (and perhaps some near it); `involved(id)` is called for each triangle whose
  // piece (below) proves part of abc: abc stays proved while none of those changes. Let S be
  // the slab of points within H = kOverlaySlab × ε of abc's plane and π the projection onto
  // that plane. Each triangle R of M meeting S over abc is cut to S and its projection to
  // abc: a convex piece P_R of abc. Over a convex piece the distance to R is convex, so its
  // largest value is at one of P_R's corners: max over them ≤ ε proves every point of P_R
  // within ε of R. The pieces cover abc when M is closed (a 2-cycle) and meets neither face
  // of S over abc: then the degree of π on M ∩ S (preimages counted +1 where a triangle
  // projects in abc's orientation, −1 where it projects reversed) is one integer D over all
  // of abc, D × area(abc) = Σ signed area(P_R), and where D ≥ 1 every point of abc lies in
  // some P_R of a triangle projected in abc's orientation. So: no triangle of M crossing a
  // face of S over abc (tested on a band a hair thicker than the face, over abc grown a
  // hair), every piece of a triangle projected in abc's orientation within ε at its corners,
  // and the signed areas summing to at least half abc's area. False otherwise (the other
  // proofs may still succeed). Only for closed meshes (overlay_).
  template <typename Near, typename Involved>
  bool overlay_proves(const Point3& a, const Point3& b, const Point3& c, const Near& each_near,
                      const Involved& involved) {
    const Point3 ab = sub(b, a);
    const Point3 ac = sub(c, a);
    Point3 n = cross(ab, ac);
    const double twice_area = std::sqrt(dot(n, n));
    const double lab = std::sqrt(dot(ab, ab));
    if (!(twice_area > 0.0) || !(lab > 0.0)) return false;
    for (double& x : n) x /= twice_area;
    const Point3 e1 = {ab[0] / lab, ab[1] / lab, ab[2] / lab};
    const Point3 e2 = cross(n, e1);
    auto local = [&](const Point3& p) {
      const Point3 d = sub(p, a);
      return LocalPoint{dot(d, e1), dot(d, e2), dot(d, n)};
    };
    const LocalPoint tc = local(c);
    // abc's sides as lines: (x, y) lies inside side k when edge[k] · (x, y, 1) >= 0 (unit
    // normals, so the value is the distance; corners counter-clockwise in x, y).
    std::array<std::array<double, 3>, 3> edge{};
    {
      const std::array<std::array<double, 2>, 3> t = {{{0.0, 0.0}, {lab, 0.0}, {tc.x, tc.y}}};
      for (int k = 0; k < 3; ++k) {
        const auto& p = t[k];
        const auto& q = t[(k + 1) % 3];
        const double len = std::sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]));
        if (!(len > 0.0)) return false;
        edge[k] = {-(q[1] - p[1]) / len, (q[0] - p[0]) / len, 0.0};
        edge[k][2] = -(edge[k][0] * p[0] + edge[k][1] * p[1]);
      }
    }
    const double slab = kOverlaySlab * eps_;
    const double hair = 1e-6 * eps_;  // far above the coordinates' rounding
    // The part of `poly` (overwritten) inside abc grown by `grow`, into `out`.
    auto in_triangle = [&](LocalPolygon& poly, LocalPolygon& out, double grow) {
      clip(poly, out, [&](const LocalPoint& x) {
        return edge[0][0] * x.x + edge[0][1] * x.y + edge[0][2] + grow;
      });
      clip(out, poly, [&](const LocalPoint& x) {
        return edge[1][0] * x.x + edge[1][1] * x.y + edge[1][2] + grow;
      });
      clip(poly, out, [&](const LocalPoint& x) {
        return edge[2][0] * x.x + edge[2][1] * x.y + edge[2][2] + grow;
      });
    };
    LocalPolygon poly{};  // zeroed once a proof, not once a reference triangle
    LocalPolygon work{};
    LocalPolygon piece{};
    const double lo_x = std::min({0.0, lab, tc.x});
    const double hi_x = std::max({0.0, lab, tc.x});
    const double lo_y = 0.0;
    const double hi_y = tc.y;
    Point3 lo = a;
    Point3 hi = a;
    for (const Point3* p : {&a, &b, &c}) {
      for (double side : {-slab - hair, slab + hair}) {
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min(lo[k], (*p)[k] + side * n[k]);
          hi[k] = std::max(hi[k], (*p)[k] + side * n[k]);
        }
      }
    }
    double signed_twice_areas = 0.0;
    bool proved = true;
    each_near(lo, hi, [&](const std::array<Point3, 3>& rp, std::uint32_t id) {
      if (!proved) return;
      poly.n = 3;
      poly.overflow = false;
      for (int k = 0; k < 3; ++k) poly.p[k] = local(rp[k]);
      const LocalPoint& p0 = poly.p[0];
      const LocalPoint& p1 = poly.p[1];
      const LocalPoint& p2 = poly.p[2];
      const double h_lo = std::min({p0.h, p1.h, p2.h});
      const double h_hi = std::max({p0.h, p1.h, p2.h});
      if (h_lo > slab + hair || h_hi < -slab - hair) return;
      if (std::max({p0.x, p1.x, p2.x}) < lo_x - hair ||
          std::min({p0.x, p1.x, p2.x}) > hi_x + hair ||
          std::max({p0.y, p1.y, p2.y}) < lo_y - hair ||
          std::min({p0.y, p1.y, p2.y}) > hi_y + hair) {
        return;  // beside abc's box
      }
      const double orientation = (p1.x - p0.x) * (p2.y - p0.y) - (p1.y - p0.y) * (p2.x - p0.x);
      // Every corner of the piece is a point (x, y) of abc's plane with (x, y, h) on the
      // reference triangle (clipping interpolates along it), so its distance to that triangle
      // is at most |h|, searched exactly only beyond ε.
      auto within = [&](const LocalPolygon& part) {
        for (int k = 0; k < part.n; ++k) {
          const LocalPoint& x = part.p[k];
          if (std::abs(x.h) <= eps_) continue;
          const Point3 q = {a[0] + x.x * e1[0] + x.y * e2[0], a[1] + x.x * e1[1] + x.y * e2[1],
                            a[2] + x.x * e1[2] + x.y * e2[2]};
          if (detail::point_triangle_distance_squared(q, rp[0], rp[1], rp[2]) > eps2_) {
            return false;
          }
        }
        return true;
      };
      // The common case: the reference triangle inside abc's prism and the slab, its own piece.
      bool inside = h_lo > -slab + hair && h_hi < slab - hair;
      for (int k = 0; k < 3 && inside; ++k) {
        for (const LocalPoint& x : {p0, p1, p2}) {
          if (edge[k][0] * x.x + edge[k][1] * x.y + edge[k][2] < hair) inside = false;
        }
      }
      if (!inside) {
        for (double face : {slab, -slab}) {
          if (h_lo > face + hair || h_hi < face - hair) continue;
          clip(poly, work, [&](const LocalPoint& x) { return face + hair - x.h; });
          clip(work, piece, [&](const LocalPoint& x) { return x.h - (face - hair); });
          in_triangle(piece, work, hair);
          if (work.n > 0 || work.overflow) {
            proved = false;  // the reference crosses a face of the slab over abc
            return;
          }
        }
        clip(poly, work, [&](const LocalPoint& x) { return slab - x.h; });
        clip(work, piece, [&](const LocalPoint& x) { return x.h + slab; });
        in_triangle(piece, work, 0.0);  // the piece, in work
        if (work.overflow) {
          proved = false;
          return;
        }
        if (work.n < 3) return;
      }
      signed_twice_areas += inside ? orientation : twice_signed_area(work);
      if (orientation > 0.0) {
        if (!within(inside ? poly : work)) proved = false;
        involved(id);
      }
    });
    return proved && signed_twice_areas >= 0.5 * twice_area;
  }

  // Every point of surface triangle t within ε of the reference: first without a search, from
  // its corners' distances (1-Lipschitz: a point p of t is within d(w) + |p − w| of the
  // reference for each corner w, and within cover_radius of its nearest corner), else by
  // near_reference.
  bool triangle_near_reference(const Triangle& t) {
    const Point3& a = pos_[t[0]];
    const Point3& b = pos_[t[1]];
    const Point3& c = pos_[t[2]];
    const std::array<double, 3> d = {vertex_distance(t[0]), vertex_distance(t[1]),
                                     vertex_distance(t[2])};
    if (!std::isfinite(std::max({d[0], d[1], d[2]}))) return false;  // a corner ε or more away
    // Every proof is sound, so which one proves t first changes only the time (but for a
    // searched point exactly ε away, which the halvings refuse and the overlay may prove): the
    // corner test without a search first; then the searched halvings where they can
    // succeed (kBisectDepth halvings at the longest side leave parts of about half t's cover
    // radius, so not beyond 2 ε), else the overlay first.
    const double radius = cover_radius(a, b, c);
    if (std::max({d[0], d[1], d[2]}) + radius * (1.0 + 1e-12) <= eps_) return true;
    auto near_reference_triangles = [&](const Point3& lo, const Point3& hi, const auto& f) {
      ref_grid_.visit_box(lo, hi, ref_stamp_, next_query(),
                          [&](std::uint32_t r) { f(corners(Patch{r, 0, 0}), r); });
    };
    auto overlay = [&] {
      if (!overlay_ || !overlay_proves(a, b, c, near_reference_triangles, [](std::uint32_t) {})) {
        return false;
      }
      ++stats_.overlay_proofs;
      return true;
    };
    const bool overlay_first = radius > kHalvingsReach * eps_;
    if (overlay_first && overlay()) return true;
    const Proof proof = corners_prove(a, b, c, d, 0);
    if (proof != Proof::unknown) return proof == Proof::yes;
    if (!overlay_first && overlay()) return true;
    return near_reference(a, b, c, 0);
  }

  void push_heap(std::uint32_t from, std::uint32_t to) {
    if (held_[from]) return;
    const Candidate c = candidate(from, to);
    if (!beyond_local_limit(c)) heap_.push(c);
  }

  // A candidate whose quadric estimate exceeds the local limit is never queued (popped, it
  // would be passed over: its cost stays as it is until a collapse onto either end changes
  // its quadric, which queues it anew), so the queue holds only what may be tried.
  bool beyond_local_limit(const Candidate& c) {
    if (local_rms2_ > 0.0 && c.cost > local_rms2_ * plane_weight(c.from, c.to)) {
      ++stats_.passed_over_local_error;
      return true;
    }
    return false;
  }

  bool stale(const Candidate& c) const {
    return c.from_version != version_[c.from] || c.to_version != version_[c.to];
  }

  // Appends the candidate u → v (a heap only once run() has made it one).
  void push(std::uint32_t from, std::uint32_t to) {
    if (held_[from]) return;
    const Candidate c = candidate(from, to);
    if (!beyond_local_limit(c)) heap_.append(c);
  }

  // The summed weight of the planes in the quadric of edge from → to: the trace of its matrix
  // (each plane's normal is a unit vector), so cost / weight is the weighted mean square.
  double plane_weight(std::uint32_t from, std::uint32_t to) const {
    const auto& a = quadric_[from].q;
    const auto& b = quadric_[to].q;
    return a[0] + a[3] + a[5] + b[0] + b[3] + b[5];
  }

  Candidate candidate(std::uint32_t from, std::uint32_t to) const {
    Quadric q = quadric_[from];
    q += quadric_[to];
    return {std::max(q.at(place(from, to).at), 0.0), from, to, version_[from], version_[to]};
  }

  // Where a collapse from → to leaves `to` (its own position without placement or when held),
  // as a float point of the frame and its exact position in the surface's.
  struct Placement {
    Point3 at;
    std::array<float, 3> frame;
  };
  Placement place(std::uint32_t from, std::uint32_t to) const {
    if (!move_ || held_[to]) return {pos_[to], {}};
    return realize(quadric_point(from, to));
  }

  // The point minimising the edge's quadric, regularised towards `to` (solved around it, by
  // cofactors): `to` moves along what the planes around the edge fix, hardly along what they
  // leave free. `to` itself when that point is within kStayShare × ε of it; the quadric's
  // minimum on the segment when it is more than half the edge away.
  Point3 quadric_point(std::uint32_t from, std::uint32_t to) const {
    Quadric sum = quadric_[from];
    sum += quadric_[to];
    const auto& a = sum.q;
    auto times = [&](const Point3& x) {  // A x
      return Point3{a[0] * x[0] + a[1] * x[1] + a[2] * x[2],
                    a[1] * x[0] + a[3] * x[1] + a[4] * x[2],
                    a[2] * x[0] + a[4] * x[1] + a[5] * x[2]};
    };
    const Point3& pv = pos_[to];
    const Point3 e = sub(pos_[from], pv);
    const Point3 av = times(pv);
    const Point3 g = {av[0] + a[6], av[1] + a[7], av[2] + a[8]};  // half the gradient at v
    // (A + μ I) x = −g: μ, a small share of the trace, keeps x near 0 along directions the
    // planes leave free (a flat or cylindrical neighbourhood), where A alone is singular.
    const double trace = a[0] + a[3] + a[5];
    if (!(trace > 0.0)) return pv;
    const double mu = kRegularization * trace;
    const double a0 = a[0] + mu, a3 = a[3] + mu, a5 = a[5] + mu;
    const double c00 = a3 * a5 - a[4] * a[4], c01 = a[2] * a[4] - a[1] * a5,
                 c02 = a[1] * a[4] - a[2] * a3, c11 = a0 * a5 - a[2] * a[2],
                 c12 = a[1] * a[2] - a0 * a[4], c22 = a0 * a3 - a[1] * a[1];
    const double det = a0 * c00 + a[1] * c01 + a[2] * c02;
    if (det > 0.0) {
      const Point3 x = {-(c00 * g[0] + c01 * g[1] + c02 * g[2]) / det,
                        -(c01 * g[0] + c11 * g[1] + c12 * g[2]) / det,
                        -(c02 * g[0] + c12 * g[1] + c22 * g[2]) / det};
      if (dot(x, x) <= kStayShare * kStayShare * eps2_) return pv;
      if (dot(x, x) <= 0.25 * dot(e, e)) return {pv[0] + x[0], pv[1] + x[1], pv[2] + x[2]};
    }
    const double eae = dot(e, times(e));
    if (!(eae > 0.0)) return pv;
    const double t = std::clamp(-dot(e, g) / eae, 0.0, 1.0);
    return {pv[0] + t * e[0], pv[1] + t * e[1], pv[2] + t * e[2]};
  }

  // p as a float point of the frame and the surface position to_patient makes of it (or p
  // rounded to float, without a geometry).
  Placement realize(const Point3& p) const {
    Placement out;
    if (geometry_ == nullptr) {
      for (int a = 0; a < 3; ++a) {
        out.frame[a] = static_cast<float>(p[a]);
        out.at[a] = out.frame[a];
      }
      return out;
    }
    const Point3 d = sub(p, {geometry_->origin[0], geometry_->origin[1], geometry_->origin[2]});
    for (int a = 0; a < 3; ++a) out.frame[a] = static_cast<float>(dot(inverse_[a], d));
    const Vec3 q = geometry_->apply(out.frame[0], out.frame[1], out.frame[2]);
    for (int a = 0; a < 3; ++a) out.at[a] = static_cast<float>(q[a]);
    return out;
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

  // After a collapse onto v: the edges at v anew (their cost changed: v's quadric grew), and
  // the candidates refused from its neighbours (their triangles changed) tried again.
  void requeue_around(std::uint32_t v) {
    ++version_[v];
    refused_from_[v].clear();
    std::vector<std::uint32_t>& ring = ring_;
    neighbours(v, ring);
    for (auto w : ring) {
      push_heap(v, w);
      push_heap(w, v);
    }
    for (auto w : ring) {
      for (auto x : refused_from_[w]) {
        if (x != v && !faces_of_[x].empty() && adjacent(w, x)) push_heap(w, x);
      }
      refused_from_[w].clear();
    }
  }

  bool adjacent(std::uint32_t w, std::uint32_t x) const {
    for (std::uint32_t f : faces_of_[w]) {
      const Triangle& t = s_.triangles[f];
      if (t[0] == x || t[1] == x || t[2] == x) return true;
    }
    return false;
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
    // (changed_ empty: u has no triangle off uv, which a vertex of a closed fan cannot.)
    if (n_edge != 2 || opposite[0] == opposite[1] || changed_.empty()) {
      return refuse(stats_.refused_topology);
    }
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

    // Where v goes: when it moves, its own triangles off uv change too.
    const std::size_t of_u = changed_.size();
    const Placement placed = place(u, v);
    const bool moves = placed.at != pos_[v];
    if (moves) {
      for (std::uint32_t f : faces_of_[v]) {
        if (f != on_edge[0] && f != on_edge[1]) changed_.push_back(f);
      }
    }
    // Boxes and area vectors before anything moves.
    old_boxes_.clear();
    old_normals_.clear();
    for (std::uint32_t f : changed_) {
      old_boxes_.push_back(box_of(s_.triangles[f]));
      old_normals_.push_back(triangle_area_vector(s_, s_.triangles[f]));
    }
    const Box edge_boxes[2] = {box_of(s_.triangles[on_edge[0]]), box_of(s_.triangles[on_edge[1]])};
    // v at its place while tested (back where it was if refused).
    const Point3 v_was = pos_[v];
    const std::array<float, 3> v_was_stored = s_.positions[v];
    const double v_distance_was = vertex_distance_[v];
    if (moves) {
      pos_[v] = placed.at;
      for (int a = 0; a < 3; ++a) s_.positions[v][a] = static_cast<float>(placed.at[a]);
      vertex_distance_[v] = -1.0;
    }
    auto put_back = [&](std::size_t& counter) {
      if (moves) {
        pos_[v] = v_was;
        s_.positions[v] = v_was_stored;
        vertex_distance_[v] = v_distance_was;
      }
      return refuse(counter);
    };

    // New triangles: shape, turn, distance to the reference.
    new_tri_.clear();
    for (std::size_t k = 0; k < changed_.size(); ++k) {
      Triangle t = s_.triangles[changed_[k]];
      for (auto& w : t) {
        if (w == u) w = v;
      }
      const ExtremeAngles shape = extreme_angles_of(pos_[t[0]], pos_[t[1]], pos_[t[2]]);
      if (shape.above_170 != 0 || shape.below_1 != 0) return put_back(stats_.refused_shape);
      const Point3 n_new = triangle_area_vector(s_, t);
      const Point3& n_old = old_normals_[k];
      if (dot(n_new, n_old) < kMinTurnCosine * std::sqrt(dot(n_new, n_new) * dot(n_old, n_old))) {
        return put_back(stats_.refused_shape);
      }
      new_tri_.push_back(t);
    }
    for (const Triangle& t : new_tri_) {
      if (!triangle_near_reference(t)) return put_back(stats_.refused_distance);
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
      for (std::size_t j = k + 1; j < changed_.size() && !crossing; ++j) {
        crossing = triangles_intersect(s_, changed_[k], changed_[j]);
      }
    }
    // The other live triangles, from one grid visit over the new triangles' boxes together.
    new_boxes_.clear();
    planes_.clear();
    Box all = box_of(new_tri_[0]);
    for (const Triangle& t : new_tri_) {
      new_boxes_.push_back(box_of(t));
      planes_.emplace_back(s_, t);
      for (int a = 0; a < 3; ++a) {
        all.lo[a] = std::min(all.lo[a], new_boxes_.back().lo[a]);
        all.hi[a] = std::max(all.hi[a], new_boxes_.back().hi[a]);
      }
    }
    ++visit_stamp_;
    if (!crossing) {
      grid_.visit(all, [&](std::uint32_t g, const Box& box) {
        if (crossing || !alive_[g] || face_mark_[g] == face_stamp_) return;
        if (visited_[g] == visit_stamp_) return;
        visited_[g] = visit_stamp_;
        for (std::size_t k = 0; k < changed_.size() && !crossing; ++k) {
          if (!boxes_meet(new_boxes_[k], box)) continue;
          if (planes_[k].separates(s_, new_tri_[k], s_.triangles[g])) continue;
          crossing = triangles_intersect(s_, changed_[k], g);
        }
      });
    }
    if (crossing) {
      undo();
      return put_back(stats_.refused_crossing);
    }

    // Reference triangles of every triangle changed or gone, to a triangle around v.
    candidates_.assign(changed_.begin(), changed_.end());
    if (!moves) {
      for (std::uint32_t f : faces_of_[v]) {
        if (f != on_edge[0] && f != on_edge[1]) candidates_.push_back(f);
      }
    }
    reassigned_.clear();
    renewed_.clear();
    if (++attempt_ == 0) {
      std::fill(redone_.begin(), redone_.end(), 0);
      attempt_ = 1;
    }
    // A changed triangle's parts first to its new shape (most stay covered by it).
    auto reassign_all = [&](std::uint32_t from) {
      std::uint32_t hint = alive_[from] ? from : kNoFace;
      for (const Patch& patch : refs_of_[from]) {
        if (!reassign(patch, hint)) return false;
      }
      return true;
    };
    bool covered = reassign_all(on_edge[0]) && reassign_all(on_edge[1]);
    for (std::size_t k = 0; k < changed_.size() && covered; ++k) covered = reassign_all(changed_[k]);
    if (!covered) {
      undo();
      return put_back(stats_.refused_distance);
    }

    // Commit.
    for (std::size_t k = 0; k < changed_.size(); ++k) {
      grid_.erase(changed_[k], old_boxes_[k]);
      grid_.insert(changed_[k], box_of(new_tri_[k]));
    }
    for (int e = 0; e < 2; ++e) {
      grid_.erase(on_edge[e], edge_boxes[e]);
      refs_of_[on_edge[e]].clear();
      auto drop = [&](std::uint32_t w) {
        auto& list = faces_of_[w];
        list.erase(std::find(list.begin(), list.end(), on_edge[e]));
      };
      drop(v);
      drop(opposite[e]);
    }
    for (std::uint32_t f : changed_) refs_of_[f].clear();
    for (std::size_t k = 0; k < of_u; ++k) faces_of_[v].push_back(changed_[k]);
    for (const auto& [to, patch] : reassigned_) refs_of_[to].push_back(patch);
    for (std::uint32_t r : renewed_) ++epoch_[r];
    if (moves && geometry_ != nullptr) (*frame_)[v] = placed.frame;
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
  const bool move_;
  const IndexToPatient* geometry_;
  std::vector<std::array<float, 3>>* frame_;
  std::array<Point3, 3> inverse_{};  // rows of the geometry's inverse linear part
  detail::TriangleGrid ref_grid_;
  FaceGrid grid_;
  std::vector<Point3> pos_;
  std::vector<std::vector<std::uint32_t>> faces_of_;
  std::vector<Quadric> quadric_;
  std::vector<std::uint32_t> version_;
  std::vector<std::uint8_t> held_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t mark_stamp_ = 0;
  std::vector<std::uint8_t> alive_;
  std::vector<std::uint32_t> face_mark_;
  std::uint32_t face_stamp_ = 0;
  std::vector<std::uint32_t> visited_;
  std::uint32_t visit_stamp_ = 0;
  std::vector<std::vector<Patch>> refs_of_;
  std::vector<std::uint16_t> epoch_;     // per reference triangle: its union listings' epoch
  std::vector<std::uint32_t> redone_;    // per reference triangle: the attempt that reproved it
  std::uint32_t attempt_ = 0;            // collapses tried
  std::vector<std::vector<std::uint32_t>> refused_from_;  // per vertex: refused candidates' ends
  std::vector<std::uint32_t> ref_stamp_;
  std::vector<double> vertex_distance_;  // < 0: not searched yet
  std::uint32_t query_ = 0;
  bool overlay_ = false;     // the overlay proof applies (a closed reference)
  bool union_first_ = false;  // reference triangles by the overlay proof before any split
  double local_rms2_ = 0.0;  // run()'s local_rms squared; 0: no local limit
  std::size_t live_ = 0;
  std::size_t grid_live_ = 0;  // live triangles when grid_ was made
  CollapseStats stats_;
  CandidateHeap heap_;
  // Scratch of collapse().
  std::vector<std::uint32_t> changed_;
  std::vector<Triangle> new_tri_;
  std::vector<Triangle> old_tri_;
  std::vector<std::uint32_t> ring_u_;
  std::vector<std::uint32_t> ring_;
  std::vector<std::uint32_t> ring_v_;
  std::vector<std::uint32_t> candidates_;
  std::vector<Box> old_boxes_;
  std::vector<Point3> old_normals_;
  std::vector<Box> new_boxes_;
  std::vector<PlaneSide> planes_;
  std::vector<std::pair<std::uint32_t, Patch>> reassigned_;
  std::vector<std::uint32_t> renewed_;  // reference triangles proved again by this collapse
};

}  // namespace

CollapseStats collapse_within_bound(TriangleMesh& surface, const TriangleMesh& reference,
                                    const CollapseOptions& options) {
  if (!(options.bound > 0.0) || !std::isfinite(options.bound) ||
      !(options.local_rms >= 0.0) || !std::isfinite(options.local_rms)) {
    throw std::invalid_argument(
        "collapse_within_bound: the bound must be finite and > 0, local_rms finite and >= 0");
  }
  if (options.move_vertices && options.geometry != nullptr &&
      (options.frame == nullptr || options.frame->size() != surface.positions.size())) {
    throw std::invalid_argument(
        "collapse_within_bound: placement with a geometry needs one frame position a vertex");
  }
  if (surface.triangles.empty() || reference.triangles.empty()) return {};
  Collapser collapser(surface, reference, options);
  return collapser.run(options.target, options.local_rms);
}


}  // namespace typemerge::core
