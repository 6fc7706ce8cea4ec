// LoopTriangulator (core/merge/loop_triangulation.h) on hand-made loops: convex, L-shaped, a
// collinear run on one box face, a pinch, a saddle every diagonal of which the face rule
// forbids; and the shape rule (best smallest angle, caps and needles counted).
#include "core/merge/loop_triangulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <set>
#include <utility>
#include <vector>

namespace typemerge::core::merge {
namespace {

const std::array<Vec3, 3> kIdentityAxes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
const P3 kUp{0, 0, 1};

std::vector<VertexId> loop_of(std::size_t n) {
  std::vector<VertexId> loop(n);
  for (std::size_t i = 0; i < n; ++i) loop[i] = static_cast<VertexId>(i);
  return loop;
}

double projected_area(const std::vector<Position>& p, const Triangle& t) {
  const P3 a = to_double(p[t[0]]);
  const P3 b = to_double(p[t[1]]);
  const P3 c = to_double(p[t[2]]);
  return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
}

double polygon_area(const std::vector<Position>& p) {
  double twice = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Position& a = p[i];
    const Position& b = p[(i + 1) % p.size()];
    twice += double(a[0]) * b[1] - double(a[1]) * b[0];
  }
  return 0.5 * twice;
}

// Smallest angle of a triangle of positions, in degrees.
double smallest_angle(const Position& a, const Position& b, const Position& c) {
  auto angle = [](const Position& o, const Position& p, const Position& q) {
    const P3 u = sub(to_double(p), to_double(o));
    const P3 v = sub(to_double(q), to_double(o));
    return std::acos(std::clamp(dot(u, v) / std::sqrt(dot(u, u) * dot(v, v)), -1.0, 1.0)) *
           180.0 / std::numbers::pi;
  };
  return std::min({angle(a, b, c), angle(b, c, a), angle(c, a, b)});
}

double smallest_angle(const std::vector<Position>& p, const std::vector<Triangle>& ts) {
  double worst = 180;
  for (const Triangle& t : ts) worst = std::min(worst, smallest_angle(p[t[0]], p[t[1]], p[t[2]]));
  return worst;
}

// The best smallest angle over every triangulation of the convex polygon p[first..last].
double best_smallest_angle(const std::vector<Position>& p, std::size_t first, std::size_t last) {
  if (last < first + 2) return 180;
  double best = 0;
  for (std::size_t k = first + 1; k < last; ++k) {
    best = std::max(best, std::min({smallest_angle(p[first], p[k], p[last]),
                                    best_smallest_angle(p, first, k),
                                    best_smallest_angle(p, k, last)}));
  }
  return best;
}

// The contract's checks: n − 2 triangles, each counter-clockwise about +z with a projected
// twice-area above kMinDoubleArea, tiling the polygon's area; no new edge (or whole triangle)
// on one face of the box.
void expect_valid_triangulation(const std::vector<Position>& p, const Box& box,
                                const std::vector<Triangle>& ts) {
  const std::size_t n = p.size();
  ASSERT_EQ(ts.size(), n - 2);
  double area = 0;
  const FaceTest faces(box);
  std::set<std::pair<VertexId, VertexId>> loop_edges;
  for (VertexId i = 0; i < n; ++i) loop_edges.insert({i, static_cast<VertexId>((i + 1) % n)});
  for (const Triangle& t : ts) {
    EXPECT_GT(2 * projected_area(p, t), kMinDoubleArea);
    area += projected_area(p, t);
    EXPECT_EQ(faces.mask(p[t[0]]) & faces.mask(p[t[1]]) & faces.mask(p[t[2]]), 0u);
    for (int k = 0; k < 3; ++k) {
      const VertexId a = t[k];
      const VertexId b = t[(k + 1) % 3];
      if (loop_edges.count({a, b}) != 0) continue;
      EXPECT_EQ(faces.mask(p[a]) & faces.mask(p[b]), 0u) << "new edge " << a << "-" << b;
    }
  }
  EXPECT_NEAR(area, polygon_area(p), 1e-9);
}

TEST(LoopTriangulation, AConvexLoopGetsTheBestSmallestAngle) {
  // An irregular convex hexagon, its vertices inside the box (on no face).
  const std::vector<Position> p{{1, 1, 5},   {6, 1.5f, 5}, {8, 4, 5},
                                {7, 7, 5},   {3, 8, 5},    {1.2f, 5, 5}};
  const Box box{{0, 0, 0}, {10, 10, 10}};
  LoopTriangulator triangulator(kIdentityAxes);
  std::vector<Triangle> out;
  ASSERT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kDone);
  expect_valid_triangulation(p, box, out);
  EXPECT_NEAR(smallest_angle(p, out), best_smallest_angle(p, 0, p.size() - 1), 1e-9);
  EXPECT_EQ(triangulator.extremes().above_170, 0u);
  EXPECT_EQ(triangulator.extremes().below_1, 0u);
}

TEST(LoopTriangulation, AnLShapedLoopIsTiledInsideItsOutline) {
  // The L (0,0) (4,0) (4,2) (2,2) (2,4) (0,4) in the box [0,4]² × [0,1]: its reflex corner
  // on the top face, the others on the side faces.
  const std::vector<Position> p{{0, 0, 0.5f}, {4, 0, 0.5f}, {4, 2, 0.5f},
                                {2, 2, 1},    {2, 4, 0.5f}, {0, 4, 0.5f}};
  const Box box{{0, 0, 0}, {4, 4, 1}};
  LoopTriangulator triangulator(kIdentityAxes);
  std::vector<Triangle> out;
  ASSERT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kDone);
  expect_valid_triangulation(p, box, out);
  for (const Triangle& t : out) {  // every centroid inside the L
    const double x = (p[t[0]][0] + p[t[1]][0] + p[t[2]][0]) / 3.0;
    const double y = (p[t[0]][1] + p[t[1]][1] + p[t[2]][1]) / 3.0;
    EXPECT_FALSE(x > 2 && y > 2) << x << ", " << y;
  }
}

TEST(LoopTriangulation, ACollinearRunOnOneFaceGetsNoEdgeAlongThatFace) {
  // Three loop vertices on the face y = 0, in a row: no ear may join the run's ends.
  const std::vector<Position> p{{0.5f, 0, 0.5f}, {1, 0, 0.5f}, {1.5f, 0, 0.5f},
                                {2, 1, 0.5f},    {1, 2, 0.5f}, {0, 1, 0.5f}};
  const Box box{{0, 0, 0}, {2, 2, 1}};
  LoopTriangulator triangulator(kIdentityAxes);
  std::vector<Triangle> out;
  ASSERT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kDone);
  expect_valid_triangulation(p, box, out);
}

TEST(LoopTriangulation, APinchedLoopIsNotSimple) {
  // Two loop vertices, one on the top face and one on the bottom face, project to one point.
  const std::vector<Position> p{{0, 0, 0.5f}, {2, 0, 0.5f}, {1, 1, 1},
                                {2, 2, 0.5f}, {0, 2, 0.5f}, {1, 1, 0}};
  const Box box{{0, 0, 0}, {2, 2, 1}};
  LoopTriangulator triangulator(kIdentityAxes);
  EXPECT_FALSE(triangulator.is_simple(loop_of(p.size()), p, box, kUp));
  std::vector<Triangle> out;
  EXPECT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kNotSimple);
  EXPECT_TRUE(out.empty());
  // The same loop without the pinch (the bottom vertex moved inwards) is simple.
  std::vector<Position> open = p;
  open[5] = {0.5f, 1, 0};
  EXPECT_TRUE(triangulator.is_simple(loop_of(open.size()), open, box, kUp));
}

TEST(LoopTriangulation, ALoopWhoseEveryDiagonalLiesOnAFaceIsStuck) {
  // A saddle: opposite corners on the top face, the other two on the bottom face.
  const std::vector<Position> p{{0, 1, 1}, {1, 0, 0}, {2, 1, 1}, {1, 2, 0}};
  const Box box{{0, 0, 0}, {2, 2, 1}};
  LoopTriangulator triangulator(kIdentityAxes);
  std::vector<Triangle> out{{7, 8, 9}};
  EXPECT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kStuck);
  EXPECT_EQ(out, (std::vector<Triangle>{{7, 8, 9}}));  // nothing added
}

TEST(LoopTriangulation, FlipsRaiseTheSmallestAngleOfAFan) {
  // A long thin convex loop: ear clipping alone tends to fan it; the flips must reach the
  // best smallest angle of any triangulation.
  const std::vector<Position> p{{1, 1, 5},   {3, 0.8f, 5}, {5, 0.7f, 5}, {7, 0.8f, 5},
                                {9, 1, 5},   {7, 1.6f, 5}, {5, 1.7f, 5}, {3, 1.6f, 5}};
  const Box box{{0, 0, 0}, {10, 10, 10}};
  LoopTriangulator triangulator(kIdentityAxes);
  std::vector<Triangle> out;
  ASSERT_EQ(triangulator.triangulate(loop_of(p.size()), p, box, kUp, true, out),
            Triangulation::kDone);
  expect_valid_triangulation(p, box, out);
  EXPECT_NEAR(smallest_angle(p, out), best_smallest_angle(p, 0, p.size() - 1), 1e-9);
}

TEST(LoopTriangulation, CapsAndNeedlesAreCountedInMillimetres) {
  // A triangle fine in index space (angles 45°, 45°, 90°) is a cap and a needle at once on a
  // grid whose y step is 0.01 mm (angles about 0.6°, 0.6°, 178.9° in mm): counted once each.
  const std::vector<Position> p{{1, 1, 5}, {2, 1, 5}, {1.5f, 1.5f, 5}};
  const Box box{{0, 0, 0}, {10, 10, 10}};
  LoopTriangulator in_index(kIdentityAxes);
  std::vector<Triangle> out;
  ASSERT_EQ(in_index.triangulate(loop_of(3), p, box, kUp, true, out), Triangulation::kDone);
  EXPECT_EQ(in_index.extremes().below_1, 0u);
  LoopTriangulator squeezed({{{1, 0, 0}, {0, 0.01, 0}, {0, 0, 1}}});
  out.clear();
  ASSERT_EQ(squeezed.triangulate(loop_of(3), p, box, kUp, true, out), Triangulation::kDone);
  EXPECT_EQ(squeezed.extremes().below_1, 1u);
  EXPECT_EQ(squeezed.extremes().above_170, 1u);
}

}  // namespace
}  // namespace typemerge::core::merge
