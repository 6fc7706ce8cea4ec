#include "core/self_intersections.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>

#include "core/plane_side.h"

namespace typemerge::core {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Segment = Kernel::Segment_3;
using Triangle = Kernel::Triangle_3;
using Point2 = Kernel::Point_2;
using Segment2 = Kernel::Segment_2;
using Triangle2 = Kernel::Triangle_2;
using Box =
    CGAL::Box_intersection_d::Box_with_info_d<double, 3, std::uint32_t,
                                              CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;

Point point(const TriangleMesh& mesh, std::uint32_t v) {
  const auto& p = mesh.positions[v];
  return {p[0], p[1], p[2]};  // float → double is exact: the test sees the stored coordinates
}

bool degenerate(const TriangleMesh& mesh, std::uint32_t t) {
  const auto& c = mesh.triangles[t];
  // Certainly not collinear when the rounded cross product has a component beyond its error
  // (each component is one 2x2 determinant of rounded differences: |error| <= 3δ·permanent
  // + O(δ²), bounded here by 4δ); otherwise CGAL decides exactly.
  const auto& p = mesh.positions[c[0]];
  const auto& q = mesh.positions[c[1]];
  const auto& r = mesh.positions[c[2]];
  const double e1[3] = {double{q[0]} - p[0], double{q[1]} - p[1], double{q[2]} - p[2]};
  const double e2[3] = {double{r[0]} - p[0], double{r[1]} - p[1], double{r[2]} - p[2]};
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3;
    const int j = (k + 2) % 3;
    const double minor = e1[i] * e2[j] - e1[j] * e2[i];
    if (std::abs(minor) > 0x1p-51 * (std::abs(e1[i] * e2[j]) + std::abs(e1[j] * e2[i]))) {
      return false;
    }
  }
  return CGAL::collinear(point(mesh, c[0]), point(mesh, c[1]), point(mesh, c[2]));
}

// The sign of orient3d(a, b, c, d) = det[a − d, b − d, c − d] when double arithmetic decides
// it for certain (Shewchuk's o3derrboundA, as in PlaneSide), else 0.
int certain_orientation(const std::array<float, 3>& a, const std::array<float, 3>& b,
                        const std::array<float, 3>& c, const std::array<float, 3>& d) {
  const double adx = double{a[0]} - d[0], ady = double{a[1]} - d[1], adz = double{a[2]} - d[2];
  const double bdx = double{b[0]} - d[0], bdy = double{b[1]} - d[1], bdz = double{b[2]} - d[2];
  const double cdx = double{c[0]} - d[0], cdy = double{c[1]} - d[1], cdz = double{c[2]} - d[2];
  const double det =
      adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady);
  const double permanent = (std::abs(bdx * cdy) + std::abs(cdx * bdy)) * std::abs(adz) +
                           (std::abs(cdx * ady) + std::abs(adx * cdy)) * std::abs(bdz) +
                           (std::abs(adx * bdy) + std::abs(bdx * ady)) * std::abs(cdz);
  constexpr double kBound = (7.0 + 56.0 * 0x1p-53) * 0x1p-53;
  if (det > kBound * permanent) return 1;
  if (-det > kBound * permanent) return -1;
  return 0;
}

// Whether segment (p, q) meets triangle t, given that p and q lie certainly on strictly
// opposite sides of t's plane: it crosses the plane at one point, inside t exactly when the
// three orientations of (p, q) against t's edges agree. 1 / 0 when certain, −1 when not (then
// CGAL decides). Saddle-shaped fans make this the common case of triangles sharing a vertex.
int crossing_segment_meets(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& t,
                           std::uint32_t p, std::uint32_t q) {
  const auto& x = mesh.positions;
  int sign = 0;
  for (int k = 0; k < 3; ++k) {
    const int o = certain_orientation(x[p], x[q], x[t[k]], x[t[(k + 1) % 3]]);
    if (o == 0) return -1;
    if (sign == 0) {
      sign = o;
    } else if (o != sign) {
      return 0;
    }
  }
  return 1;
}

// The axis on which all the given vertices have the same coordinate, or -1. Flat caps (the
// closed volume border, planar faces) lie in such planes: orientation there is exactly zero,
// which CGAL decides only by exact arithmetic, 50-100x slower than its filters; in the plane
// the test is two-dimensional and filtered again.
template <std::size_t N>
int common_axis(const TriangleMesh& mesh, const std::array<std::uint32_t, N>& v) {
  for (int k = 0; k < 3; ++k) {
    bool same = true;
    for (std::size_t i = 1; i < N && same; ++i) {
      same = mesh.positions[v[i]][k] == mesh.positions[v[0]][k];
    }
    if (same) return k;
  }
  return -1;
}

Point2 point2(const TriangleMesh& mesh, std::uint32_t v, int axis) {
  const auto& p = mesh.positions[v];
  return {p[axis == 0 ? 1 : 0], p[axis == 2 ? 1 : 2]};
}

// Stops the box search once enough pairs are found.
struct Enough {};

// triangles_intersect with the two triangles' planes already set up.
bool intersect(const TriangleMesh& mesh, std::uint32_t s, std::uint32_t t, const PlaneSide& plane_s,
               const PlaneSide& plane_t) {
  const auto& a = mesh.triangles[s];
  const auto& b = mesh.triangles[t];
  // Shared corners by index, as bits 3i + j (i-th of a is j-th of b), without branches: most
  // pairs a search meets share a corner, in no predictable pattern.
  unsigned mask = 0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) mask |= static_cast<unsigned>(a[i] == b[j]) << (3 * i + j);
  }
  const unsigned rest = mask & (mask - 1);
  const int shared = (mask != 0) + (rest != 0) + ((rest & (rest - 1)) != 0);
  int ai[2] = {0, 0};
  int bj[2] = {0, 0};
  if (mask != 0) {
    const int first = std::countr_zero(mask);
    ai[0] = first / 3;
    bj[0] = first % 3;
    if (rest != 0) {
      const int second = std::countr_zero(rest);
      ai[1] = second / 3;
      bj[1] = second % 3;
    }
  }
  if (shared >= 3) return true;  // the same triangle twice
  auto triangle2 = [&](const std::array<std::uint32_t, 3>& c, int axis) {
    return Triangle2(point2(mesh, c[0], axis), point2(mesh, c[1], axis), point2(mesh, c[2], axis));
  };
  if (shared == 2) {
    // Not coplanar for certain: a plain mesh edge.
    if (plane_s.side(mesh.positions[b[3 - bj[0] - bj[1]]]) != 0) return false;
    const int axis =
        common_axis(mesh, std::array<std::uint32_t, 4>{a[0], a[1], a[2], b[3 - bj[0] - bj[1]]});
    if (axis >= 0) {
      const Point2 u = point2(mesh, a[ai[0]], axis);
      const Point2 v = point2(mesh, a[ai[1]], axis);
      const auto side_a = CGAL::orientation(u, v, point2(mesh, a[3 - ai[0] - ai[1]], axis));
      const auto side_b = CGAL::orientation(u, v, point2(mesh, b[3 - bj[0] - bj[1]], axis));
      return side_a != CGAL::COLLINEAR && side_a == side_b;
    }
    // Shared edge (u, v): overlap only when the other corners are coplanar with it and on the
    // same side of it.
    const Point u = point(mesh, a[ai[0]]);
    const Point v = point(mesh, a[ai[1]]);
    const Point ra = point(mesh, a[3 - ai[0] - ai[1]]);
    const Point rb = point(mesh, b[3 - bj[0] - bj[1]]);
    return CGAL::coplanar(u, v, ra, rb) &&
           CGAL::coplanar_orientation(u, v, ra, rb) == CGAL::POSITIVE;
  }
  auto triangle = [&](const std::array<std::uint32_t, 3>& c) {
    return Triangle(point(mesh, c[0]), point(mesh, c[1]), point(mesh, c[2]));
  };
  if (shared == 1) {
    // They meet at the shared corner; they cross when either's opposite edge meets the other.
    const int i = ai[0];
    const int j = bj[0];
    const std::array<std::uint32_t, 2> far_a{a[(i + 1) % 3], a[(i + 2) % 3]};
    const std::array<std::uint32_t, 2> far_b{b[(j + 1) % 3], b[(j + 2) % 3]};
    auto meets = [&](const PlaneSide& plane, const std::array<std::uint32_t, 3>& tri,
                     const std::array<std::uint32_t, 2>& edge) {
      // The edge's box apart from the triangle's: no common point (exact: float comparisons).
      // Most pairs of a fan are decided here.
      const auto& p0 = mesh.positions[edge[0]];
      const auto& p1 = mesh.positions[edge[1]];
      for (int k = 0; k < 3; ++k) {
        const float edge_lo = std::min(p0[k], p1[k]);
        const float edge_hi = std::max(p0[k], p1[k]);
        const float tri_lo = std::min(
            {mesh.positions[tri[0]][k], mesh.positions[tri[1]][k], mesh.positions[tri[2]][k]});
        const float tri_hi = std::max(
            {mesh.positions[tri[0]][k], mesh.positions[tri[1]][k], mesh.positions[tri[2]][k]});
        if (edge_hi < tri_lo || tri_hi < edge_lo) return false;
      }
      const int s0 = plane.side(mesh.positions[edge[0]]);
      const int s1 = plane.side(mesh.positions[edge[1]]);
      if (s0 != 0 && s0 == s1) return false;  // on one side
      if (s0 != 0 && s1 == -s0) {
        const int verdict = crossing_segment_meets(mesh, tri, edge[0], edge[1]);
        if (verdict >= 0) return verdict == 1;
      }
      const int axis =
          common_axis(mesh, std::array<std::uint32_t, 5>{tri[0], tri[1], tri[2], edge[0], edge[1]});
      if (axis >= 0) {
        return CGAL::do_intersect(triangle2(tri, axis), Segment2(point2(mesh, edge[0], axis),
                                                                 point2(mesh, edge[1], axis)));
      }
      return CGAL::do_intersect(triangle(tri), Segment(point(mesh, edge[0]), point(mesh, edge[1])));
    };
    return meets(plane_s, a, far_b) || meets(plane_t, b, far_a);
  }
  if (plane_s.one_side(mesh, b) || plane_t.one_side(mesh, a)) return false;
  const int axis =
      common_axis(mesh, std::array<std::uint32_t, 6>{a[0], a[1], a[2], b[0], b[1], b[2]});
  if (axis >= 0) return CGAL::do_intersect(triangle2(a, axis), triangle2(b, axis));
  return CGAL::do_intersect(triangle(a), triangle(b));
}

}  // namespace

bool triangles_intersect(const TriangleMesh& mesh, std::uint32_t s, std::uint32_t t) {
  return intersect(mesh, s, t, PlaneSide(mesh, mesh.triangles[s]),
                   PlaneSide(mesh, mesh.triangles[t]));
}

namespace {

// The grid's cell size, in mean triangle box extents: fewer pairs per cell against fewer cells
// per triangle. Abdomen, whole surfaces, two rounds each: bone (535 k triangles) 0.87-0.90 s at
// 0.7, 0.65-0.76 at 1, 0.64-0.68 at 1.5, 0.49-0.64 at 2, 0.62-0.70 at 3; mc's 946 k triangles
// 1.08-1.18 s at 1, 0.98-1.01 at 2, 0.96-1.01 at 3.
constexpr double kCellsPerExtent = 2.0;

struct TriangleBox {
  std::array<float, 3> lo;
  std::array<float, 3> hi;
};

bool boxes_meet(const TriangleBox& a, const TriangleBox& b) {
  for (int k = 0; k < 3; ++k) {
    if (a.hi[k] < b.lo[k] || b.hi[k] < a.lo[k]) return false;
  }
  return true;
}

// Calls test(s, t) once for every pair of listed triangles whose boxes meet, s flagged (when
// `only_with` is given). A sparse uniform grid: cells kCellsPerExtent mean box extents, each
// triangle entered in every cell its box meets, entries grouped by cell with a radix sort
// (a surface fills few of its bounding box's cells, so no dense cell table), and each pair
// taken in the first cell both meet. For the surfaces the project makes (triangles a few
// voxels at most) this is about twice as fast as CGAL's box_intersection_d (header); false,
// having called nothing, when the sizes are too uneven for a grid (a triangle would need too
// many cells, e.g. a decimated mesh) or the grid too large for 32-bit cell keys (kept to 32
// bits: the type-merging guard holds these arrays beside a piece).
template <typename Test>
bool grid_pairs(const std::vector<TriangleBox>& boxes, const std::vector<std::uint32_t>& ids,
                std::span<const std::uint8_t> only_with, Test&& test) {
  const std::size_t n = boxes.size();
  if (n == 0) return true;
  std::array<double, 3> lo{1e300, 1e300, 1e300};
  std::array<double, 3> hi{-1e300, -1e300, -1e300};
  std::array<double, 3> extent{0, 0, 0};
  for (const TriangleBox& b : boxes) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min<double>(lo[k], b.lo[k]);
      hi[k] = std::max<double>(hi[k], b.hi[k]);
      extent[k] += double{b.hi[k]} - b.lo[k];
    }
  }
  std::array<double, 3> inverse{};
  std::array<std::int64_t, 3> dims{};
  double cells = 1;
  for (int k = 0; k < 3; ++k) {
    const double cell = std::max(kCellsPerExtent * extent[k] / static_cast<double>(n),
                                 (hi[k] - lo[k]) * 1e-6 + 1e-30);
    inverse[k] = 1.0 / cell;
    dims[k] =
        std::max<std::int64_t>(1, static_cast<std::int64_t>((hi[k] - lo[k]) * inverse[k]) + 1);
    cells *= static_cast<double>(dims[k]);
  }
  if (cells > 0x1p32) return false;
  auto cell_of = [&](double x, int k) {
    const auto c = static_cast<std::int64_t>((x - lo[k]) * inverse[k]);
    return static_cast<std::int32_t>(std::clamp<std::int64_t>(c, 0, dims[k] - 1));
  };
  std::vector<std::array<std::int32_t, 6>> range(n);
  std::size_t entries = 0;
  for (std::size_t i = 0; i < n; ++i) {
    std::int64_t count = 1;
    for (int k = 0; k < 3; ++k) {
      range[i][k] = cell_of(boxes[i].lo[k], k);
      range[i][k + 3] = cell_of(boxes[i].hi[k], k);
      count *= std::int64_t{range[i][k + 3]} - range[i][k] + 1;
    }
    entries += static_cast<std::size_t>(count);
  }
  if (entries > 32 * n + 1024) return false;
  // Entries: cell key and triangle, in two arrays.
  std::vector<std::uint32_t> keys;
  std::vector<std::uint32_t> members;
  keys.reserve(entries);
  members.reserve(entries);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& r = range[i];
    for (std::int64_t z = r[2]; z <= r[5]; ++z) {
      for (std::int64_t y = r[1]; y <= r[4]; ++y) {
        for (std::int64_t x = r[0]; x <= r[3]; ++x) {
          keys.push_back(static_cast<std::uint32_t>((z * dims[1] + y) * dims[0] + x));
          members.push_back(static_cast<std::uint32_t>(i));
        }
      }
    }
  }
  // LSD radix sort of the entries by key, 11 bits a pass (an 8 KiB count table: 14 bits were
  // slower), as many passes as the largest key needs; stable, so a cell's members stay in
  // triangle order.
  {
    const auto largest = static_cast<std::uint64_t>(cells);
    const int bits = std::max(1, static_cast<int>(std::bit_width(largest)));
    const int passes = (bits + 10) / 11;
    const int digit = (bits + passes - 1) / passes;
    const std::uint64_t radix_mask = (std::uint64_t{1} << digit) - 1;
    std::vector<std::uint32_t> keys_out(entries);
    std::vector<std::uint32_t> members_out(entries);
    std::vector<std::uint32_t> count(radix_mask + 2);
    for (int pass = 0; pass < passes; ++pass) {
      const int shift = pass * digit;
      std::fill(count.begin(), count.end(), 0u);
      for (std::uint32_t key : keys) ++count[((key >> shift) & radix_mask) + 1];
      for (std::size_t b = 1; b < count.size(); ++b) count[b] += count[b - 1];
      for (std::size_t e = 0; e < entries; ++e) {
        const std::uint32_t slot = count[(keys[e] >> shift) & radix_mask]++;
        keys_out[slot] = keys[e];
        members_out[slot] = members[e];
      }
      keys.swap(keys_out);
      members.swap(members_out);
    }
  }
  const bool subset = !only_with.empty();
  std::vector<std::uint8_t> flag(n, 1);  // per box: one indirection less in the pair loop
  if (subset) {
    for (std::size_t i = 0; i < n; ++i) flag[i] = only_with[ids[i]] != 0 ? 1 : 0;
  }
  auto flagged = [&](std::uint32_t i) { return flag[i] != 0; };
  for (std::size_t first = 0; first < entries;) {
    std::size_t last = first + 1;
    while (last < entries && keys[last] == keys[first]) ++last;
    const std::uint64_t key = keys[first];
    const auto x = static_cast<std::int32_t>(key % static_cast<std::uint64_t>(dims[0]));
    const auto y = static_cast<std::int32_t>((key / static_cast<std::uint64_t>(dims[0])) %
                                             static_cast<std::uint64_t>(dims[1]));
    const auto z = static_cast<std::int32_t>(key / static_cast<std::uint64_t>(dims[0] * dims[1]));
    for (std::size_t p = first; p < last; ++p) {
      const std::uint32_t i = members[p];
      const bool flagged_i = flagged(i);
      for (std::size_t q = p + 1; q < last; ++q) {
        const std::uint32_t j = members[q];
        if (!flagged_i && !flagged(j)) continue;
        // Only in the first cell the two share.
        if (x != std::max(range[i][0], range[j][0]) || y != std::max(range[i][1], range[j][1]) ||
            z != std::max(range[i][2], range[j][2])) {
          continue;
        }
        if (!boxes_meet(boxes[i], boxes[j])) continue;
        if (flagged_i) {
          test(ids[i], ids[j]);
        } else {
          test(ids[j], ids[i]);
        }
      }
    }
    first = last;
  }
  return true;
}

// The same with CGAL's box_intersection_d (a streamed segment tree): for meshes whose
// triangle sizes are too uneven for the grid, e.g. decimated ones.
template <typename Test>
void library_pairs(const std::vector<TriangleBox>& boxes, const std::vector<std::uint32_t>& ids,
                   std::span<const std::uint8_t> only_with, Test&& test) {
  std::vector<Box> library;
  library.reserve(boxes.size());
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const TriangleBox& b = boxes[i];
    library.emplace_back(CGAL::Bbox_3(b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]),
                         ids[i]);
  }
  // The search reorders and copies what it is given: it gets pointers (the ids stay the
  // boxes' addresses, as the ID policy needs).
  std::vector<const Box*> pointers;
  pointers.reserve(library.size());
  for (const Box& box : library) pointers.push_back(&box);
  const bool subset = !only_with.empty();
  auto visit = [&](const Box* x, const Box* y) {
    std::uint32_t s = x->info();
    std::uint32_t t = y->info();
    if (subset) {
      // s the flagged one; a pair of two flagged triangles is met twice: take it once.
      if (s == t) return;
      if (only_with[s] == 0) std::swap(s, t);
      if (only_with[t] != 0 && t < s) return;
    }
    test(s, t);
  };
  if (subset) {
    std::vector<const Box*> flagged;
    for (const Box* box : pointers) {
      if (only_with[box->info()] != 0) flagged.push_back(box);
    }
    CGAL::box_intersection_d<CGAL::Sequential_tag>(flagged.begin(), flagged.end(), pointers.begin(),
                                                   pointers.end(), visit);
  } else {
    CGAL::box_self_intersection_d<CGAL::Sequential_tag>(pointers.begin(), pointers.end(), visit);
  }
}

}  // namespace

SelfIntersections find_self_intersections(const TriangleMesh& mesh, std::size_t max_pairs,
                                          std::span<const std::uint8_t> only_with) {
  return detail::find_self_intersections_by(mesh, max_pairs, only_with, false);
}

namespace detail {

SelfIntersections find_self_intersections_by(const TriangleMesh& mesh, std::size_t max_pairs,
                                             std::span<const std::uint8_t> only_with,
                                             bool library) {
  assert(only_with.empty() || only_with.size() == mesh.triangles.size());
  SelfIntersections found;
  std::vector<TriangleBox> boxes;
  std::vector<std::uint32_t> ids;
  boxes.reserve(mesh.triangles.size());
  ids.reserve(mesh.triangles.size());
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    if (degenerate(mesh, t)) {
      ++found.degenerate_triangles;
      continue;
    }
    TriangleBox box{{1e30f, 1e30f, 1e30f}, {-1e30f, -1e30f, -1e30f}};
    for (std::uint32_t v : mesh.triangles[t]) {
      for (int k = 0; k < 3; ++k) {
        box.lo[k] = std::min(box.lo[k], mesh.positions[v][k]);
        box.hi[k] = std::max(box.hi[k], mesh.positions[v][k]);
      }
    }
    boxes.push_back(box);
    ids.push_back(t);
  }
  auto test = [&](std::uint32_t s, std::uint32_t t) {
    if (!triangles_intersect(mesh, s, t)) return;
    found.pairs.push_back({std::min(s, t), std::max(s, t)});
    if (max_pairs != 0 && found.pairs.size() >= max_pairs) throw Enough{};
  };
  try {
    if (library || !grid_pairs(boxes, ids, only_with, test)) {
      library_pairs(boxes, ids, only_with, test);
    }
  } catch (const Enough&) {
    found.truncated = true;
  }
  std::sort(found.pairs.begin(), found.pairs.end());
  return found;
}

}  // namespace detail

}  // namespace typemerge::core
