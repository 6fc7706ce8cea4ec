// RayParity: the grid of shadows counts the crossings that testing every triangle counts, and
// tells inside from outside for closed surfaces.
#include "core/ray_parity.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "core/marching_cubes.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

using Point = std::array<double, 3>;

Point to_point(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

// The parity by testing every triangle of `ids` (all when empty).
bool every_triangle_parity(const TriangleMesh& mesh, const std::vector<std::uint32_t>& ids,
                           const Point& point) {
  std::size_t crossings = 0;
  auto test = [&](std::uint32_t i) {
    const auto& t = mesh.triangles[i];
    crossings += ray_crosses(point, to_point(mesh.positions[t[0]]), to_point(mesh.positions[t[1]]),
                             to_point(mesh.positions[t[2]]))
                     ? 1
                     : 0;
  };
  if (ids.empty()) {
    for (std::uint32_t i = 0; i < mesh.triangles.size(); ++i) test(i);
  } else {
    for (std::uint32_t i : ids) test(i);
  }
  return crossings % 2 == 1;
}

// Query points: every vertex (on the surface), every centroid, points just off them, and
// random points in and around the mesh's box.
std::vector<Point> query_points(const TriangleMesh& mesh, unsigned seed) {
  std::vector<Point> points;
  for (std::size_t v = 0; v < mesh.positions.size(); v += 2) {
    points.push_back(to_point(mesh.positions[v]));
  }
  for (std::size_t i = 0; i < mesh.triangles.size(); i += 2) {
    const auto& t = mesh.triangles[i];
    Point c{};
    for (std::uint32_t v : t) {
      for (int k = 0; k < 3; ++k) c[k] += mesh.positions[v][k] / 3.0;
    }
    points.push_back(c);
    points.push_back({c[0] + 1e-7, c[1] - 1e-7, c[2]});
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> around(-2.0, 14.0);
  for (int i = 0; i < 3000; ++i) points.push_back({around(rng), around(rng), around(rng)});
  return points;
}

TEST(RayParity, CountsWhatEveryTriangleCounts) {
  // Noise at 0.5: hundreds of small closed shells, vertices on lattice edges.
  const Volume volume = test::noise_volume(13, 12, 11, 7);
  const TriangleMesh mesh = extract_isosurface(volume, 0.5f);
  ASSERT_GT(mesh.triangles.size(), 2000u);
  const RayParity parity(mesh);
  std::vector<std::uint32_t> odd;  // a subset, as a shell's triangles are passed
  for (std::uint32_t i = 1; i < mesh.triangles.size(); i += 2) odd.push_back(i);
  const RayParity odd_parity(mesh, odd);
  std::size_t inside = 0;
  std::size_t checked = 0;
  for (const Point& p : query_points(mesh, 11)) {
    const bool all = every_triangle_parity(mesh, {}, p);
    ASSERT_EQ(parity.inside(p), all) << p[0] << " " << p[1] << " " << p[2];
    ASSERT_EQ(odd_parity.inside(p), every_triangle_parity(mesh, odd, p))
        << p[0] << " " << p[1] << " " << p[2];
    inside += all ? 1 : 0;
    ++checked;
  }
  // Both answers occur, so the comparison above is not all "outside".
  EXPECT_GT(inside, checked / 20);
  EXPECT_LT(inside, checked - checked / 20);
}

TEST(RayParity, InsideAndOutsideOfASphere) {
  const Volume volume = test::sphere_volume(20, 6.0, 9.0, 9.5, 10.0);
  const TriangleMesh mesh = extract_isosurface(volume, 0.0f);
  const RayParity parity(mesh);
  EXPECT_TRUE(parity.inside({9.0, 9.5, 10.0}));
  EXPECT_TRUE(parity.inside({13.5, 9.5, 10.0}));
  EXPECT_FALSE(parity.inside({15.5, 9.5, 10.0}));
  EXPECT_FALSE(parity.inside({-100, 0, 0}));
  EXPECT_FALSE(parity.inside({9.0, 9.5, 1e6}));
}

TEST(RayParity, NoTrianglesNothingInside) {
  const TriangleMesh empty;
  EXPECT_FALSE(RayParity(empty).inside({0, 0, 0}));
  const Volume volume = test::sphere_volume(12, 4.0, 6.0, 6.0, 6.0);
  const TriangleMesh mesh = extract_isosurface(volume, 0.0f);
  EXPECT_FALSE(RayParity(mesh, std::vector<std::uint32_t>{}).inside({6, 6, 6}));
}

}  // namespace
}  // namespace typemerge::core
