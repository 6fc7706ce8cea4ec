// Tests of keep_largest_component, remove_small_components and fill_cavities on unions of
// balls, a hollow shell and hand-made tetrahedra. Balls are at least three voxels apart, so
// each one's surface is exactly the surface of that ball extracted alone, and expected
// volumes come from extracting it alone.
#include "mesh/components.h"

#include <gtest/gtest.h>

#include "core/mesh_checks.h"
#include "mesh/test_surfaces.h"

namespace typemerge::mesh {
namespace {

using test::Ball;

constexpr std::int64_t kN = 48;
const Ball kBig{16.3, 16.2, 16.1, 10.0};
const Ball kMedium{37.2, 36.9, 15.3, 5.0};
const Ball kSmall{36.6, 12.3, 38.4, 2.4};
const Ball kSpeck{12.2, 37.7, 38.1, 1.3};

double volume_alone(const Ball& b) { return core::check_mesh(test::sphere(kN, b)).volume; }

TEST(Components, KeepLargestRemovesEveryOtherComponent) {
  core::TriangleMesh mesh = test::balls(kN, {kSpeck, kBig, kSmall, kMedium});
  ASSERT_EQ(core::check_mesh(mesh).components, 4u);

  const ComponentReport report = keep_largest_component(mesh);

  EXPECT_EQ(report.components_before, 4u);
  EXPECT_EQ(report.components_after, 1u);
  EXPECT_EQ(report.removed_components, 3u);
  const core::TriangleMesh big = test::sphere(kN, kBig);
  EXPECT_EQ(mesh.triangles.size(), big.triangles.size());
  EXPECT_EQ(mesh.positions.size(), big.positions.size());  // unused vertices gone
  EXPECT_NEAR(report.kept_volume, volume_alone(kBig), 1e-9 * volume_alone(kBig));
  const double debris = volume_alone(kSpeck) + volume_alone(kSmall) + volume_alone(kMedium);
  EXPECT_NEAR(report.removed_volume, debris, 1e-9 * debris);
  EXPECT_TRUE(report.validity.valid());
  EXPECT_EQ(report.validity.check.components, 1u);
}

TEST(Components, VolumeThresholdKeepsExactlyTheBigOnes) {
  core::TriangleMesh mesh = test::balls(kN, {kSpeck, kBig, kSmall, kMedium});
  // Volumes ≈ 4189, 524, 58 and 9 mm³: a threshold of 100 keeps the first two.
  const ComponentReport report = remove_small_components(mesh, 100.0);

  EXPECT_EQ(report.removed_components, 2u);
  EXPECT_EQ(report.components_after, 2u);
  const double kept = volume_alone(kBig) + volume_alone(kMedium);
  EXPECT_NEAR(report.kept_volume, kept, 1e-9 * kept);
  const double removed = volume_alone(kSmall) + volume_alone(kSpeck);
  EXPECT_NEAR(report.removed_volume, removed, 1e-9 * removed);
  EXPECT_EQ(mesh.triangles.size(),
            test::sphere(kN, kBig).triangles.size() + test::sphere(kN, kMedium).triangles.size());
  EXPECT_TRUE(report.validity.valid());
}

TEST(Components, ThresholdZeroRemovesNothing) {
  core::TriangleMesh mesh = test::balls(kN, {kBig, kSpeck});
  const std::size_t triangles = mesh.triangles.size();
  const ComponentReport report = remove_small_components(mesh, 0.0);
  EXPECT_EQ(report.removed_components, 0u);
  EXPECT_EQ(mesh.triangles.size(), triangles);
}

TEST(Components, ShellsSharingAVertexAreOneComponent) {
  core::TriangleMesh mesh = test::bowtie_tetrahedra();
  const ComponentReport report = keep_largest_component(mesh);
  EXPECT_EQ(report.components_before, 1u);
  EXPECT_EQ(report.removed_components, 0u);
  EXPECT_EQ(mesh.triangles.size(), 8u);
}

TEST(Components, EmptyMeshStaysEmpty) {
  core::TriangleMesh mesh;
  EXPECT_EQ(keep_largest_component(mesh).components_after, 0u);
  EXPECT_EQ(fill_cavities(mesh).components_after, 0u);
  EXPECT_TRUE(mesh.empty());
}

// A hollow ball (outer radius 12, cavity radius 7) with a solid island of radius 3 floating
// in the cavity, and a separate solid ball beside it.
TEST(Components, FillCavitiesTurnsAHollowShellIntoOneSolidShell) {
  const Ball centre{17.2, 16.8, 17.1, 0.0};
  const Ball island{17.5, 16.4, 17.9, 3.0};
  const Ball beside{39.1, 38.8, 39.3, 5.0};
  core::TriangleMesh mesh = test::hollow_shell(kN, centre, 12.0, 7.0, {island, beside});
  const core::MeshCheck before = core::check_mesh(mesh);
  ASSERT_EQ(before.components, 4u);  // outer wall, cavity wall, island, ball beside
  ASSERT_TRUE(before.closed_manifold());

  const ComponentReport report = fill_cavities(mesh);

  EXPECT_EQ(report.removed_components, 2u);  // the cavity wall and the island in it
  EXPECT_EQ(report.components_after, 2u);
  const double solid = volume_alone({centre.x, centre.y, centre.z, 12.0}) + volume_alone(beside);
  EXPECT_NEAR(report.kept_volume, solid, 1e-9 * solid);
  EXPECT_NEAR(report.validity.check.volume, solid, 1e-9 * solid);
  EXPECT_TRUE(report.validity.valid());
  EXPECT_GT(report.kept_volume, before.volume);  // the cavity (minus island) was filled
}

// The same hollow ball, with a smaller hollow ball beside it: keeping the largest solid keeps
// its cavity (a skull keeps its cranial cavity), drops the island floating in that cavity and
// the other solid with its own cavity; filling afterwards makes it one shell.
TEST(Components, KeepLargestKeepsTheCavityOfTheLargestSolidOnly) {
  const Ball centre{17.2, 16.8, 17.1, 0.0};
  const Ball island{17.5, 16.4, 17.9, 3.0};
  const Ball beside{39.1, 38.8, 39.3, 6.0};
  core::TriangleMesh mesh = test::hollow_shell(kN, centre, 12.0, 7.0, {island});
  // The ball beside is hollow too: its cavity wall (radius 3) is a negative shell outside the
  // big ball, dropped with its solid.
  const core::TriangleMesh second = test::hollow_shell(kN, beside, 6.0, 3.0);
  const auto offset = static_cast<std::uint32_t>(mesh.positions.size());
  mesh.positions.insert(mesh.positions.end(), second.positions.begin(), second.positions.end());
  for (auto t : second.triangles) {
    for (auto& v : t) v += offset;
    mesh.triangles.push_back(t);
  }
  const core::MeshCheck before = core::check_mesh(mesh);
  ASSERT_EQ(before.components, 5u);  // outer, cavity, island; ball beside and its cavity
  ASSERT_TRUE(before.closed_manifold());

  const ComponentReport report = keep_largest_component(mesh);

  EXPECT_EQ(report.components_after, 2u);  // the outer wall and its cavity wall
  EXPECT_EQ(report.removed_components, 3u);
  const double wall = core::check_mesh(test::hollow_shell(kN, centre, 12.0, 7.0)).volume;
  EXPECT_NEAR(report.kept_volume, wall, 1e-9 * wall);
  EXPECT_LT(report.kept_volume, 0.85 * volume_alone({centre.x, centre.y, centre.z, 12.0}));
  EXPECT_TRUE(report.validity.valid());

  const ComponentReport filled = fill_cavities(mesh);
  EXPECT_EQ(filled.components_after, 1u);
  const double solid = volume_alone({centre.x, centre.y, centre.z, 12.0});
  EXPECT_NEAR(filled.kept_volume, solid, 1e-9 * solid);

  // Filled at once: the same single shell.
  core::TriangleMesh again = test::hollow_shell(kN, centre, 12.0, 7.0, {island, beside});
  const ComponentReport at_once = keep_largest_component(again, Cavities::fill);
  EXPECT_EQ(at_once.components_after, 1u);
  EXPECT_EQ(again.triangles.size(), mesh.triangles.size());
  EXPECT_NEAR(at_once.kept_volume, solid, 1e-9 * solid);
}

TEST(Components, FillCavitiesLeavesSolidsAlone) {
  core::TriangleMesh mesh = test::balls(kN, {kBig, kMedium, kSpeck});
  const ComponentReport report = fill_cavities(mesh);
  EXPECT_EQ(report.removed_components, 0u);
  EXPECT_EQ(report.components_after, 3u);
}

void expect_same_check(const core::MeshCheck& a, const core::MeshCheck& b) {
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.boundary_edges, b.boundary_edges);
  EXPECT_EQ(a.non_manifold_edges, b.non_manifold_edges);
  EXPECT_EQ(a.inconsistent_edges, b.inconsistent_edges);
  EXPECT_EQ(a.non_manifold_vertices, b.non_manifold_vertices);
  EXPECT_EQ(a.degenerate_triangles, b.degenerate_triangles);
  EXPECT_EQ(a.components, b.components);
  EXPECT_EQ(a.euler_characteristic, b.euler_characteristic);
  EXPECT_EQ(a.volume, b.volume);  // the same sums in the same order: bit for bit
  EXPECT_EQ(a.area, b.area);
}

// Given the check of their input, the steps derive their result's instead of checking it
// again: it must be exactly check_mesh's, for every step, whether or not they removed
// anything; a check that does not fit the input (not clean, or of another mesh) is not used.
TEST(Components, AKnownCheckGivesTheResultsCheckExactly) {
  const core::TriangleMesh balls = test::balls(kN, {kSpeck, kBig, kSmall, kMedium});
  const core::TriangleMesh shell =
      test::hollow_shell(kN, kBig, 12.0, 7.0, {Ball{16.3, 16.2, 16.1, 3.0}});
  for (const core::TriangleMesh* input : {&balls, &shell}) {
    const core::MeshCheck before = core::check_mesh(*input);
    ASSERT_TRUE(before.closed_manifold());
    for (int step = 0; step < 5; ++step) {
      SCOPED_TRACE(step);
      core::TriangleMesh mesh = *input;
      ComponentReport report;
      if (step == 0) report = keep_largest_component(mesh, Cavities::keep, &before);
      if (step == 1) report = keep_largest_component(mesh, Cavities::fill, &before);
      if (step == 2) report = remove_small_components(mesh, 100.0, &before);
      if (step == 3) report = remove_small_components(mesh, 0.0, &before);  // removes nothing
      if (step == 4) report = fill_cavities(mesh, &before);
      expect_same_check(report.validity.check, core::check_mesh(mesh));
    }
  }
  // A check of something else (another mesh, a defect) is ignored, not trusted.
  core::TriangleMesh mesh = balls;
  core::MeshCheck wrong = core::check_mesh(shell);
  ComponentReport report = remove_small_components(mesh, 100.0, &wrong);
  expect_same_check(report.validity.check, core::check_mesh(mesh));
  mesh = balls;
  wrong = core::check_mesh(balls);
  wrong.boundary_edges = 1;
  report = remove_small_components(mesh, 100.0, &wrong);
  expect_same_check(report.validity.check, core::check_mesh(mesh));
}

}  // namespace
}  // namespace typemerge::mesh
