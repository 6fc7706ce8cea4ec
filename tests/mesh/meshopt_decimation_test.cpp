// Tests of decimate_with_meshopt and of decimate_mesh's fall back to OpenMesh: on closed
// analytic surfaces meshoptimizer's result is taken (target reached, closed manifold, the
// input's Euler characteristic and components, every input vertex within max_error); where
// the bound cannot be met the input is left for OpenMesh, whose result is valid; and one
// real surface (abdomen bone, marching cubes) gives a valid result whichever library made it.
#include "mesh/meshopt_decimation.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "mesh/decimation.h"
#include "mesh/test_surfaces.h"
#include "support/test_data.h"

namespace typemerge::mesh {
namespace {

void expect_valid_like(const DecimationReport& report, const core::MeshCheck& input) {
  EXPECT_TRUE(report.validity.valid());
  for (const auto& line : report.validity.problems()) ADD_FAILURE() << line;
  EXPECT_EQ(report.validity.check.euler_characteristic, input.euler_characteristic);
  EXPECT_EQ(report.validity.check.components, input.components);
}

TEST(MeshoptDecimation, SphereReachesTheTargetClosedWithinTheBound) {
  const core::TriangleMesh original = test::sphere(48, {23.3, 23.6, 23.4, 18.0});
  core::TriangleMesh mesh = original;
  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 10;
  options.max_error = 0.5;  // meshopt aims at kErrorFactor of it: loose enough for the target

  const DecimationReport report = decimate_with_meshopt(mesh, options);

  EXPECT_EQ(report.fallback, "");
  EXPECT_EQ(report.decimator, Decimator::meshopt);
  EXPECT_TRUE(report.reached_target);
  EXPECT_EQ(report.triangles_after, mesh.triangles.size());
  EXPECT_LE(mesh.triangles.size(), options.target_triangles + 1);
  expect_valid_like(report, core::check_mesh(original));
  EXPECT_EQ(core::find_self_intersections(mesh).pairs.size(), 0u);
  // The bound as OpenMesh states it (every input vertex), and the sampled figure reported.
  EXPECT_LE(core::max_vertex_distance(original, mesh), 0.5);
  EXPECT_GE(report.meshopt.sampled_error, 0.0);
  EXPECT_LE(report.meshopt.sampled_error, 0.5);
  EXPECT_EQ(mesh.normals.size(), mesh.positions.size());
}

TEST(MeshoptDecimation, TorusKeepsItsHole) {
  const core::TriangleMesh original = test::torus(48, 14.0, 6.0);
  const core::MeshCheck input = core::check_mesh(original);
  ASSERT_EQ(input.euler_characteristic, 0);
  core::TriangleMesh mesh = original;
  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 8;
  options.max_error = 0.5;

  const DecimationReport report = decimate_with_meshopt(mesh, options);

  EXPECT_EQ(report.fallback, "");
  EXPECT_LT(report.triangles_after, report.triangles_before / 4);
  expect_valid_like(report, input);
  EXPECT_LE(core::max_vertex_distance(original, mesh), 0.5);
}

// A bumpy sphere (no two triangles coplanar) within 1e-4 mm: no collapse meets the bound, so
// meshoptimizer's result is refused ("nothing reduced" or a far point) and the input goes to
// OpenMesh, whose result is valid.
TEST(MeshoptDecimation, ABoundThatCannotBeMetFallsBackToOpenMesh) {
  const core::TriangleMesh original = test::noisy_sphere(32, {15.3, 15.6, 15.4, 11.0}, 0.3, 7);
  ASSERT_TRUE(core::check_mesh(original).closed_manifold());
  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 10;
  options.max_error = 1e-4;
  options.decimator = Decimator::meshopt;
  core::TriangleMesh mesh = original;
  const DecimationReport tried = decimate_with_meshopt(mesh, options);
  EXPECT_NE(tried.fallback, "");
  EXPECT_EQ(mesh.triangles, original.triangles);  // left as it was

  const DecimationReport report = decimate_mesh(mesh, options);
  EXPECT_EQ(report.decimator, Decimator::openmesh);
  EXPECT_EQ(report.fallback, tried.fallback);
  ASSERT_FALSE(report.warnings.empty());
  EXPECT_NE(report.warnings.front().find("OpenMesh"), std::string::npos);
  expect_valid_like(report, core::check_mesh(original));
}

TEST(MeshoptDecimation, InputThatIsNotClosedManifoldGoesToOpenMesh) {
  core::TriangleMesh mesh = test::bowtie_tetrahedra();
  DecimationOptions options;
  options.decimator = Decimator::meshopt;
  const DecimationReport tried = decimate_with_meshopt(mesh, options);
  EXPECT_NE(tried.fallback.find("input not closed manifold"), std::string::npos);
  const DecimationReport report = decimate_mesh(mesh, options);
  EXPECT_EQ(report.decimator, Decimator::openmesh);
  EXPECT_EQ(report.split_vertices, 1u);
  EXPECT_TRUE(report.validity.valid());
}

// Abdomen bone by marching cubes (about 900 k triangles) to a tenth within 0.1 mm. Heavy (the
// fall back runs OpenMesh, about 30 s): optimised builds without sanitizers only.
TEST(MeshoptDecimation, AbdomenBoneStaysValidWhicheverLibraryMadeIt) {
#if !defined(NDEBUG) || defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "heavy real-data test: optimised builds without sanitizers only";
#endif
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const auto scan = dicom::scan_folder(data / "ct" / "abdomen", {});
  ASSERT_TRUE(scan.default_series.has_value());
  const core::Volume volume = dicom::load_series(scan.series[*scan.default_series]).volume;
  core::TriangleMesh mesh = core::extract_isosurface(volume, 226.0f);  // the bone preset's iso
  core::to_patient(mesh, volume.geometry());
  const core::TriangleMesh original = mesh;
  const core::MeshCheck input = core::check_mesh(original, 0);
  ASSERT_TRUE(input.closed_manifold());

  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 10;
  options.max_error = 0.1;
  options.decimator = Decimator::meshopt;
  const DecimationReport report = decimate_mesh(mesh, options);

  EXPECT_GT(report.meshopt.passes, 0);
  EXPECT_LT(report.triangles_after, report.triangles_before);
  expect_valid_like(report, input);
  if (report.decimator == Decimator::meshopt) {
    EXPECT_EQ(report.fallback, "");
    EXPECT_LE(core::max_vertex_distance(original, mesh, 0), 0.1);
    EXPECT_EQ(core::find_self_intersections(mesh).pairs.size(), 0u);
  } else {
    EXPECT_NE(report.fallback, "");
  }
}

}  // namespace
}  // namespace typemerge::mesh
