// Tests of vertex_to_mesh_distance / mesh_distance: exact values on drawn meshes, agreement
// with brute force (every point against every triangle) on MC and merged surfaces, and the
// same answer for any thread count.
#include "core/mesh_distance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "core/marching_cubes.h"
#include "core/triangle_grid.h"
#include "core/type_merging.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

MeshDistance brute_force(const TriangleMesh& from, const TriangleMesh& to) {
  MeshDistance out;
  out.points = from.positions.size();
  auto p3 = [](const std::array<float, 3>& p) { return std::array<double, 3>{p[0], p[1], p[2]}; };
  double sum = 0.0;
  for (const auto& p : from.positions) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& t : to.triangles) {
      best = std::min(best, detail::point_triangle_distance_squared(
                                p3(p), p3(to.positions[t[0]]), p3(to.positions[t[1]]),
                                p3(to.positions[t[2]])));
    }
    out.max = std::max(out.max, std::sqrt(best));
    sum += std::sqrt(best);
  }
  out.mean = sum / static_cast<double>(from.positions.size());
  return out;
}

//  A unit square in z = 0 (two triangles) and a point set above it:
//    (0.5, 0.5, 2) → 2 (over the face), (3, 0, 0) → 2 (off the edge x = 1), (2, 2, 0) → √2.
TEST(MeshDistance, ExactOnASquare) {
  TriangleMesh square;
  square.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  TriangleMesh points;
  points.positions = {{0.5f, 0.5f, 2.0f}, {3, 0, 0}, {2, 2, 0}};
  const MeshDistance d = vertex_to_mesh_distance(points, square, 1);
  EXPECT_DOUBLE_EQ(d.max, 2.0);
  EXPECT_NEAR(d.mean, (2.0 + 2.0 + std::sqrt(2.0)) / 3.0, 1e-12);
  EXPECT_EQ(d.points, 3u);
  EXPECT_DOUBLE_EQ(max_vertex_distance(square, square), 0.0);
}

// A bent quad cut along one diagonal (first) or the other (second): the same four vertices,
// so vertex samples see no difference; the surfaces differ by 0.5 in the middle.
std::pair<TriangleMesh, TriangleMesh> bent_quads() {
  TriangleMesh a;
  a.positions = {{0, 0, 0}, {2, 0, 0}, {2, 2, 1}, {0, 2, 0}};
  a.triangles = {{0, 1, 2}, {0, 2, 3}};
  TriangleMesh b = a;
  b.triangles = {{0, 1, 3}, {1, 2, 3}};
  return {a, b};
}

// Surface samples find the bent quads' difference.
TEST(MeshDistance, SurfaceSamplesSeeInsideTriangles) {
  const auto [a, b] = bent_quads();
  EXPECT_EQ(mesh_distance(a, b).hausdorff(), 0.0);
  const auto sampled = surface_distance(a, b, 0.05);
  // The farthest points are the diagonals' midpoints: B's (1, 1, 0) lies 2 / sqrt(20) from A's
  // plane z = y / 2 and projects inside A's triangle there; A's (1, 1, 0.5) lies
  // 1 / sqrt(6) from B. So the Hausdorff distance is 1 / sqrt(5), found to within the spacing.
  EXPECT_NEAR(sampled.hausdorff(), 1.0 / std::sqrt(5.0), 0.01);
  EXPECT_GT(sampled.mean(), 0.0);
  const TriangleMesh points = surface_samples(a, 0.5);
  EXPECT_GT(points.positions.size(), 4u + 2u * 10u);  // interior points of both triangles
  EXPECT_TRUE(points.triangles.empty());
}

// Area samples: every vertex, then every centroid, then ⌈area × density⌉ points spread by
// area (a triangle of three times the area gets three times the points), all on the surface,
// the same for the same seed.
TEST(MeshDistance, AreaSamplesSpreadByArea) {
  TriangleMesh mesh;  // two separate triangles of areas 1 and 3
  mesh.positions = {{0, 0, 0}, {2, 0, 0}, {0, 1, 0}, {5, 0, 1}, {8, 0, 1}, {5, 2, 1}};
  mesh.triangles = {{0, 1, 2}, {3, 4, 5}};
  const TriangleMesh samples = area_samples(mesh, 100.0, 7);
  ASSERT_EQ(samples.positions.size(), 6u + 2u + 400u);
  EXPECT_TRUE(samples.triangles.empty());
  for (std::size_t v = 0; v < 6; ++v) EXPECT_EQ(samples.positions[v], mesh.positions[v]);
  EXPECT_NEAR(samples.positions[6][0], 2.0f / 3.0f, 1e-6);
  EXPECT_NEAR(samples.positions[7][1], 2.0f / 3.0f, 1e-6);
  std::size_t on_first = 0;
  for (std::size_t i = 8; i < samples.positions.size(); ++i) {
    const auto& p = samples.positions[i];
    if (p[2] == 0.0f) {
      ++on_first;
      EXPECT_GE(p[0], 0.0f);
      EXPECT_GE(p[1], 0.0f);
      EXPECT_LE(p[0] / 2.0f + p[1], 1.0f + 1e-6f);  // inside the first triangle
    } else {
      EXPECT_EQ(p[2], 1.0f);
    }
  }
  EXPECT_EQ(on_first, 100u);
  EXPECT_LE(vertex_to_mesh_distance(samples, mesh, 1).max, 1e-6);
  // Uniform inside the triangle: three quarters of its area lies at x < 1, so about 75 of its
  // 100 points do (binomial: 60 to 90 is beyond three standard deviations).
  std::size_t left = 0;
  for (std::size_t i = 8; i < samples.positions.size(); ++i) {
    if (samples.positions[i][2] == 0.0f && samples.positions[i][0] < 1.0f) ++left;
  }
  EXPECT_GT(left, 60u);
  EXPECT_LT(left, 90u);
  // Seeded: the same points again; another seed moves the spread points only.
  EXPECT_EQ(area_samples(mesh, 100.0, 7).positions, samples.positions);
  const TriangleMesh other = area_samples(mesh, 100.0, 8);
  ASSERT_EQ(other.positions.size(), samples.positions.size());
  EXPECT_TRUE(std::equal(samples.positions.begin(), samples.positions.begin() + 8,
                         other.positions.begin()));
  EXPECT_NE(other.positions, samples.positions);
  // No density: vertices and centroids only.
  EXPECT_EQ(area_samples(mesh, 0.0).positions.size(), 8u);
}

// Area samples find the bent quads' distance too, to within their spread.
TEST(MeshDistance, AreaSampledDistanceSeesInsideTriangles) {
  const auto [a, b] = bent_quads();
  const auto sampled = area_sampled_distance(a, b, 400.0, 1);
  EXPECT_LE(sampled.hausdorff(), 1.0 / std::sqrt(5.0) + 1e-6);
  EXPECT_GT(sampled.hausdorff(), 1.0 / std::sqrt(5.0) - 0.05);
  // Vertices, centroids and ⌈400 × area⌉: A's two triangles have √5 each, B's 2 and √6.
  EXPECT_EQ(sampled.a_to_b.points, 4u + 2u + 1789u);
  EXPECT_EQ(sampled.b_to_a.points, 4u + 2u + 1780u);
}

TEST(MeshDistance, PointTriangleAndSegmentDistances) {
  const std::array<double, 3> a{0, 0, 0};
  const std::array<double, 3> b{2, 0, 0};
  const std::array<double, 3> c{0, 2, 0};
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({0.5, 0.5, 3}, a, b, c), 9.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({-1, 0, 0}, a, b, c), 1.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({2, 2, 0}, a, b, c), 2.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({3, 0, 1}, a, b, c), 2.0);
  // Degenerate (collinear) triangle: distance to the segment.
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({1, 1, 0}, a, b, {1, 0, 0}), 1.0);
  EXPECT_DOUBLE_EQ(detail::point_segment_distance_squared({1, 3, 0}, a, b), 9.0);
  EXPECT_DOUBLE_EQ(detail::point_segment_distance_squared({4, 0, 0}, a, b), 4.0);
  EXPECT_DOUBLE_EQ(detail::point_segment_distance_squared({0, 1, 0}, a, a), 1.0);  // a point
}

TEST(MeshDistance, EmptyMeshes) {
  TriangleMesh empty;
  TriangleMesh square;
  square.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}};
  square.triangles = {{0, 1, 2}};
  EXPECT_EQ(vertex_to_mesh_distance(empty, square).max, 0.0);
  EXPECT_TRUE(std::isinf(vertex_to_mesh_distance(square, empty).max));
}

TEST(MeshDistance, MatchesBruteForceOnMergedSurfaces) {
  const Volume volume = test::sphere_volume(26, 9.7, 12.3, 12.6, 12.1);
  const TriangleMesh mc = extract_isosurface(volume, 0.0f);
  const TriangleMesh tm = extract_type_merged(volume, 0.0f);
  // Far points too: a shifted copy is outside the grid of the other mesh.
  TriangleMesh shifted = tm;
  for (auto& p : shifted.positions) p[0] += 17.0f;
  using Pair = std::pair<const TriangleMesh*, const TriangleMesh*>;
  for (const auto& [from, to] : {Pair{&mc, &tm}, Pair{&tm, &mc}, Pair{&shifted, &mc},
                                 Pair{&mc, &shifted}}) {
    const MeshDistance fast = vertex_to_mesh_distance(*from, *to, 1);
    const MeshDistance slow = brute_force(*from, *to);
    EXPECT_DOUBLE_EQ(fast.max, slow.max);
    EXPECT_NEAR(fast.mean, slow.mean, 1e-12 * std::max(1.0, slow.mean));
  }
  EXPECT_LE(max_vertex_distance(mc, tm), MergeOptions{}.epsilon_voxels);
  const SymmetricMeshDistance both = mesh_distance(mc, tm, 1);
  EXPECT_DOUBLE_EQ(both.hausdorff(), std::max(brute_force(mc, tm).max, brute_force(tm, mc).max));
}

// A search seeded with any triangle (the nearest, a far one, none) finds what the unseeded
// search finds, and leaves the nearest triangle as the next seed.
TEST(MeshDistance, SeededSearchMatchesTheUnseededOne) {
  const Volume volume = test::sphere_volume(26, 9.7, 12.3, 12.6, 12.1);
  const TriangleMesh mesh = extract_type_merged(volume, 0.0f);
  const detail::TriangleGrid grid(mesh);
  std::vector<std::uint32_t> stamp(mesh.triangles.size(), 0);
  std::uint32_t query = 0;
  const auto count = static_cast<std::uint32_t>(mesh.triangles.size());
  for (int i = 0; i < 300; ++i) {
    const double a = 0.37 * i, b = 0.11 * i, r = 0.06 * i;
    const detail::Point3 p = {12.3 + r * std::cos(a) * std::sin(b),
                              12.6 + r * std::sin(a) * std::sin(b), 12.1 + r * std::cos(b)};
    std::uint32_t nearest = count;
    const double plain = grid.nearest_squared(p, stamp, ++query,
                                              std::numeric_limits<double>::infinity(), &nearest);
    ASSERT_LT(nearest, count);
    for (std::uint32_t seed : {nearest, (nearest + count / 2) % count, 0u, count, ~0u}) {
      std::uint32_t hint = seed;
      EXPECT_EQ(grid.nearest_squared_from(p, stamp, ++query,
                                          std::numeric_limits<double>::infinity(), hint),
                plain)
          << i << " seed " << seed;
      ASSERT_LT(hint, count);
      const auto& t = mesh.triangles[hint];
      EXPECT_EQ(detail::point_triangle_distance_squared(p, detail::as_point3(mesh.positions[t[0]]),
                                                        detail::as_point3(mesh.positions[t[1]]),
                                                        detail::as_point3(mesh.positions[t[2]])),
                plain);
    }
  }
}

TEST(MeshDistance, SameForAnyThreadCount) {
  const Volume volume = test::noise_volume(24, 20, 22, 3);
  const TriangleMesh mc = extract_isosurface(volume, 0.5f);
  const TriangleMesh tm = extract_type_merged(volume, 0.5f);
  const MeshDistance one = vertex_to_mesh_distance(mc, tm, 1);
  for (unsigned threads : {2u, 3u, 0u}) {
    const MeshDistance d = vertex_to_mesh_distance(mc, tm, threads);
    EXPECT_EQ(d.max, one.max);
    EXPECT_EQ(d.mean, one.mean);
  }
}

// Point distances (the hollow wall's exact refinement): each point's distance to `to` as the
// brute force gives it (rounded to float), `cap` for every point farther than the cap and
// only for those, infinity against an empty mesh, the same for any thread count.
TEST(MeshDistance, PointDistancesMatchBruteForceUpToTheCap) {
  const Volume volume = test::sphere_volume(26, 9.7, 12.3, 12.6, 12.1);
  const TriangleMesh to = extract_type_merged(volume, 0.0f);
  std::vector<std::array<float, 3>> points;
  for (int i = 0; i < 400; ++i) {  // inside, near and far outside the sphere
    const double a = 0.37 * i, b = 0.11 * i, r = 0.05 * i;
    points.push_back({static_cast<float>(12.3 + r * std::cos(a) * std::sin(b)),
                      static_cast<float>(12.6 + r * std::sin(a) * std::sin(b)),
                      static_cast<float>(12.1 + r * std::cos(b))});
  }
  TriangleMesh cloud;
  cloud.positions = points;
  const auto exact = [&](std::size_t i) {
    TriangleMesh one;
    one.positions = {points[i]};
    return brute_force(one, to).max;
  };
  const std::vector<float> uncapped = point_to_mesh_distances(points, to, 1);
  ASSERT_EQ(uncapped.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(uncapped[i], static_cast<float>(exact(i))) << i;
  }
  const double cap = 3.0;
  const std::vector<float> capped = point_to_mesh_distances(points, to, 2, cap);
  std::size_t beyond = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (exact(i) > cap) {
      ++beyond;
      EXPECT_EQ(capped[i], static_cast<float>(cap)) << i;
    } else {
      EXPECT_EQ(capped[i], uncapped[i]) << i;
    }
  }
  EXPECT_GT(beyond, 50u);  // the cap was exercised
  for (unsigned threads : {2u, 3u}) {
    EXPECT_EQ(point_to_mesh_distances(points, to, threads), uncapped);
  }
  for (float d : point_to_mesh_distances(points, TriangleMesh{}, 1)) EXPECT_TRUE(std::isinf(d));
}

TEST(TypeMerging, ThreadedExtractionMergesToTheSameMesh) {
  const Volume volume = test::noise_volume(16, 14, 60, 9);
  ExtractOptions options;
  const TriangleMesh serial = extract_type_merged(volume, 0.5f, options);
  for (unsigned threads : {2u, 3u}) {
    options.threads = threads;
    const TriangleMesh mesh = extract_type_merged(volume, 0.5f, options);
    EXPECT_EQ(mesh.positions, serial.positions);
    EXPECT_EQ(mesh.normals, serial.normals);
    EXPECT_EQ(mesh.triangles, serial.triangles);
  }
}

}  // namespace
}  // namespace typemerge::core
