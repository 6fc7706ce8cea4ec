// Tests of check_mesh on meshes small enough to count by hand.
#include "core/mesh_checks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "core/marching_cubes.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

//        3
//       /|\          unit right tetrahedron at the origin, faces wound outward:
//      / | \         V = 1/6, A = 3·1/2 + √3/2
//     0--|--2
//      \ | /
//        1
TriangleMesh tetrahedron() {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

TEST(MeshChecks, TetrahedronIsAClosedSphere) {
  const MeshCheck c = check_mesh(tetrahedron());
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_EQ(c.vertices, 4u);
  EXPECT_EQ(c.edges, 6u);
  EXPECT_EQ(c.triangles, 4u);
  EXPECT_EQ(c.euler_characteristic, 2);
  EXPECT_EQ(c.components, 1u);
  EXPECT_DOUBLE_EQ(c.volume, 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(c.area, 1.5 + std::sqrt(3.0) / 2.0);
}

TEST(MeshChecks, InwardWindingGivesNegativeVolume) {
  TriangleMesh m = tetrahedron();
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  const MeshCheck c = check_mesh(m);
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_DOUBLE_EQ(c.volume, -1.0 / 6.0);
}

TEST(MeshChecks, OneFlippedTriangleMakesThreeInconsistentEdges) {
  TriangleMesh m = tetrahedron();
  std::swap(m.triangles[3][1], m.triangles[3][2]);
  const MeshCheck c = check_mesh(m);
  EXPECT_EQ(c.inconsistent_edges, 3u);
  EXPECT_EQ(c.boundary_edges, 0u);
}

TEST(MeshChecks, MissingTriangleLeavesABoundary) {
  TriangleMesh m = tetrahedron();
  m.triangles.pop_back();
  const MeshCheck c = check_mesh(m);
  EXPECT_EQ(c.boundary_edges, 3u);
  EXPECT_EQ(c.non_manifold_vertices, 0u);  // a fan at the border is manifold
  EXPECT_EQ(c.euler_characteristic, 1);    // a disk
}

TEST(MeshChecks, ThreeTrianglesOnOneEdgeAreNonManifold) {
  // A book with three pages on the spine 0–1.
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, -1, 0}};
  m.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const MeshCheck c = check_mesh(m);
  EXPECT_EQ(c.non_manifold_edges, 1u);
  EXPECT_EQ(c.inconsistent_edges, 1u);  // two pages use 0→1
  EXPECT_EQ(c.boundary_edges, 6u);
}

TEST(MeshChecks, TwoTetrahedraTouchingAtAVertexMakeANonManifoldVertex) {
  TriangleMesh m = tetrahedron();
  // Second tetrahedron: the first mirrored through vertex 0.
  m.positions.push_back({-1, 0, 0});
  m.positions.push_back({0, -1, 0});
  m.positions.push_back({0, 0, -1});
  m.triangles.push_back({0, 4, 5});
  m.triangles.push_back({0, 6, 4});
  m.triangles.push_back({0, 5, 6});
  m.triangles.push_back({4, 6, 5});
  const MeshCheck c = check_mesh(m);
  EXPECT_EQ(c.non_manifold_vertices, 1u);
  EXPECT_EQ(c.inconsistent_edges, 0u);
  EXPECT_NEAR(c.volume, 2.0 / 6.0, 1e-12);
  EXPECT_EQ(c.non_manifold_edges, 0u);
  EXPECT_EQ(c.boundary_edges, 0u);
  EXPECT_EQ(c.components, 1u);
  EXPECT_EQ(c.euler_characteristic, 7 - 12 + 8);
}

TEST(MeshChecks, DegenerateTrianglesAreCounted) {
  TriangleMesh m = tetrahedron();
  m.triangles.push_back({1, 1, 2});  // repeated index: ignored otherwise
  m.positions.push_back({2, 0, 0});  // collinear with 0 and 1
  m.triangles.push_back({0, 1, 4});  // zero area, still topology
  const MeshCheck c = check_mesh(m);
  EXPECT_EQ(c.degenerate_triangles, 2u);
  EXPECT_EQ(c.triangles, 5u);
  EXPECT_EQ(c.vertices, 5u);
}

TEST(MeshChecks, ComponentsAndUnusedVertices) {
  TriangleMesh m = tetrahedron();
  const TriangleMesh t = tetrahedron();
  m.positions.push_back({9, 9, 9});  // unused: not counted
  const std::uint32_t base = static_cast<std::uint32_t>(m.positions.size());
  for (auto p : t.positions) m.positions.push_back({p[0] + 5, p[1], p[2]});
  for (auto tri : t.triangles) m.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
  const MeshCheck c = check_mesh(m);
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_EQ(c.components, 2u);
  EXPECT_EQ(c.vertices, 8u);
  EXPECT_EQ(c.euler_characteristic, 4);
  EXPECT_NEAR(c.volume, 2.0 / 6.0, 1e-12);
}

// Caps (an angle above 170°) and needles (an angle below 1°), just either side of each bound.
TEST(MeshChecks, ExtremeAnglesAreCounted) {
  TriangleMesh m;
  const float needle = static_cast<float>(std::tan(0.9 * std::numbers::pi / 180.0));  // 0.9° at the origin
  const float fine = static_cast<float>(std::tan(1.1 * std::numbers::pi / 180.0));
  const float cap = static_cast<float>(std::tan(4.0 * std::numbers::pi / 180.0));  // 172° at the apex
  const float open = static_cast<float>(std::tan(6.0 * std::numbers::pi / 180.0));  // 168°
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0},      // right angle: neither
                 {1, needle, 0}, {1, fine, 0},         // 0.9° and 1.1° at the origin
                 {-1, 0, 0}, {0, cap, 0}, {0, open, 0},  // 172° and 168° at the apex
                 {0, 0, 0}};                           // coincides with vertex 0
  m.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 1, 4}, {5, 1, 6}, {5, 1, 7}, {0, 8, 2}};
  const ExtremeAngles counts = count_extreme_angles(m);
  EXPECT_EQ(counts.above_170, 1u);
  // The 0.9° triangle and the one with a zero-length edge (the 172° one's others are 4°).
  EXPECT_EQ(counts.below_1, 2u);
  EXPECT_EQ(count_extreme_angles(TriangleMesh{}).below_1, 0u);
}

TEST(MeshChecks, EmptyMesh) {
  const MeshCheck c = check_mesh(TriangleMesh{});
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_EQ(c.components, 0u);
  EXPECT_EQ(c.euler_characteristic, 0);
}

bool same(const MeshCheck& a, const MeshCheck& b) {
  return a.vertices == b.vertices && a.edges == b.edges && a.triangles == b.triangles &&
         a.boundary_edges == b.boundary_edges && a.non_manifold_edges == b.non_manifold_edges &&
         a.inconsistent_edges == b.inconsistent_edges &&
         a.non_manifold_vertices == b.non_manifold_vertices &&
         a.degenerate_triangles == b.degenerate_triangles && a.components == b.components &&
         a.euler_characteristic == b.euler_characteristic && a.volume == b.volume &&
         a.area == b.area;
}

// The bucketed check against the sorting oracle: random triangle soups (every defect at once)
// and extracted surfaces (closed, many vertices).
TEST(MeshChecks, BucketedCheckEqualsTheSortingOracle) {
  std::mt19937 random(7);
  for (int trial = 0; trial < 200; ++trial) {
    TriangleMesh soup;
    const auto n = static_cast<std::uint32_t>(3 + random() % 12);
    for (std::uint32_t v = 0; v < n; ++v) {
      soup.positions.push_back({float(random() % 4), float(random() % 4), float(random() % 4)});
    }
    const std::size_t triangles = random() % 30;
    for (std::size_t t = 0; t < triangles; ++t) {
      soup.triangles.push_back({std::uint32_t(random() % n), std::uint32_t(random() % n),
                                std::uint32_t(random() % n)});
    }
    ASSERT_TRUE(same(check_mesh(soup), detail::check_mesh_by_sorting(soup))) << trial;
  }
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const TriangleMesh mesh = extract_isosurface(test::noise_volume(12, 11, 10, seed), 0.5f);
    const MeshCheck fast = check_mesh(mesh);
    EXPECT_TRUE(same(fast, detail::check_mesh_by_sorting(mesh)));
    EXPECT_TRUE(fast.closed_manifold());
    EXPECT_GT(fast.triangles, 100u);
  }
}

// Big enough for several chunks of the parallel passes (65,536 triangles, 32,768 vertices),
// with defects of every kind spread over them: the same result as the oracle on any thread
// count, area and volume included bit for bit.
TEST(MeshChecks, ParallelCheckEqualsTheOracleOnAnyThreadCount) {
  TriangleMesh mesh = extract_isosurface(test::noise_volume(60, 58, 56, 3), 0.5f);
  ASSERT_GT(mesh.triangles.size(), 200000u);
  const auto t = mesh.triangles.size();
  mesh.triangles.push_back(mesh.triangles[t / 3]);             // an edge used four times
  std::swap(mesh.triangles[t / 2][0], mesh.triangles[t / 2][1]);  // flipped: inconsistent
  mesh.triangles.erase(mesh.triangles.begin() + static_cast<std::ptrdiff_t>(2 * t / 3));  // hole
  mesh.triangles.push_back({5, 5, 9});                          // repeated index
  mesh.positions.push_back(mesh.positions[7]);                   // zero area
  mesh.triangles.push_back({7, static_cast<std::uint32_t>(mesh.positions.size() - 1), 8});
  const MeshCheck oracle = detail::check_mesh_by_sorting(mesh);
  EXPECT_FALSE(oracle.closed_manifold());
  EXPECT_GT(oracle.non_manifold_edges, 0u);
  EXPECT_GT(oracle.inconsistent_edges, 0u);
  EXPECT_GT(oracle.boundary_edges, 0u);
  EXPECT_GE(oracle.degenerate_triangles, 2u);
  for (unsigned threads : {1u, 2u, 3u, 8u}) {
    EXPECT_TRUE(same(check_mesh(mesh, threads), oracle)) << threads;
  }
}

}  // namespace
}  // namespace typemerge::core
