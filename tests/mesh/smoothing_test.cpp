// Tests of smooth_mesh: Taubin smoothing removes noise from a bumpy sphere without shrinking
// it, where a Laplacian with the same steps shrinks it measurably.
#include "mesh/smoothing.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/mesh_checks.h"
#include "mesh/components.h"
#include "mesh/test_surfaces.h"

namespace typemerge::mesh {
namespace {

const test::Ball kBall{23.4, 23.6, 23.5, 16.0};

core::TriangleMesh bumpy_sphere() {
  core::TriangleMesh mesh = test::noisy_sphere(48, kBall, 0.4, 7);
  keep_largest_component(mesh);  // the noise may leave specks beside the surface
  return mesh;
}

TEST(Smoothing, TaubinSmoothsANoisySphereWithoutShrinkingIt) {
  core::TriangleMesh mesh = bumpy_sphere();
  const double rms_before = test::radial_rms(mesh, kBall);
  const core::MeshCheck before = core::check_mesh(mesh);
  ASSERT_TRUE(before.closed_manifold());

  SmoothingOptions options;
  options.iterations = 20;
  const SmoothingReport report = smooth_mesh(mesh, options);

  const double rms_after = test::radial_rms(mesh, kBall);
  EXPECT_LT(rms_after, 0.6 * rms_before) << rms_before << " → " << rms_after;
  EXPECT_LT(std::abs(report.relative_volume_change), 0.01);
  EXPECT_DOUBLE_EQ(report.volume_before, before.volume);
  EXPECT_NEAR(report.volume_after, core::check_mesh(mesh).volume, 1e-9 * before.volume);
  EXPECT_NEAR(report.mu, 1.0 / (0.1 - 2.0), 1e-12);
  EXPECT_TRUE(report.validity.valid());
  EXPECT_EQ(report.validity.check.triangles, before.triangles);
}

TEST(Smoothing, LaplacianShrinksWhereTaubinDoesNot) {
  core::TriangleMesh taubin = bumpy_sphere();
  core::TriangleMesh laplacian = taubin;
  SmoothingOptions options;
  options.iterations = 20;
  const SmoothingReport kept = smooth_mesh(taubin, options);
  options.method = SmoothingOptions::Method::laplacian;
  const SmoothingReport shrunk = smooth_mesh(laplacian, options);

  EXPECT_EQ(shrunk.mu, 0.0);
  EXPECT_LT(shrunk.relative_volume_change, -0.02);
  EXPECT_GT(std::abs(shrunk.relative_volume_change), 5.0 * std::abs(kept.relative_volume_change));
  // Shrinking shows as the mean radius falling below the true one.
  EXPECT_GT(test::radial_rms(laplacian, kBall), test::radial_rms(taubin, kBall));
}

TEST(Smoothing, ZeroIterationsChangesNothingButNormals) {
  core::TriangleMesh mesh = test::sphere(24, {11.5, 11.5, 11.5, 8.0});
  const auto positions = mesh.positions;
  SmoothingOptions options;
  options.iterations = 0;
  const SmoothingReport report = smooth_mesh(mesh, options);
  EXPECT_EQ(mesh.positions, positions);
  EXPECT_EQ(report.relative_volume_change, 0.0);
}

TEST(Smoothing, RecomputedNormalsPointOutward) {
  core::TriangleMesh mesh = bumpy_sphere();
  smooth_mesh(mesh);
  ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto& p = mesh.positions[v];
    const auto& n = mesh.normals[v];
    const double radial = (p[0] - kBall.x) * n[0] + (p[1] - kBall.y) * n[1] + (p[2] - kBall.z) * n[2];
    ASSERT_GT(radial, 0.0) << "vertex " << v;
  }
}

}  // namespace
}  // namespace typemerge::mesh
