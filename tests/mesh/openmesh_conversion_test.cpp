// Tests of the core ↔ OpenMesh conversion: exact round trip with orientation kept, and
// non-manifold input counted instead of crashing (or printing).
#include "mesh/detail/openmesh_conversion.h"

#include <gtest/gtest.h>

#include <utility>

#include "core/mesh_checks.h"
#include "mesh/test_surfaces.h"

namespace typemerge::mesh::detail {
namespace {

TEST(OpenMeshConversion, RoundTripKeepsEveryTriangleAndItsWinding) {
  const core::TriangleMesh original = test::sphere(24, {11.4, 11.7, 11.2, 8.0});
  ToOpenMesh converted = to_openmesh(original);
  EXPECT_EQ(converted.rejected_faces, 0u);
  EXPECT_EQ(converted.split_vertices, 0u);
  EXPECT_EQ(converted.mesh.n_faces(), original.triangles.size());
  EXPECT_EQ(converted.mesh.n_vertices(), original.positions.size());

  const core::TriangleMesh back = from_openmesh(converted.mesh);
  EXPECT_EQ(back.positions, original.positions);
  ASSERT_EQ(back.triangles.size(), original.triangles.size());
  for (std::size_t i = 0; i < back.triangles.size(); ++i) {
    // Same triangle, same cyclic order (OpenMesh may start the cycle elsewhere).
    const auto& a = back.triangles[i];
    const auto& b = original.triangles[i];
    const bool same = (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) ||
                      (a[0] == b[1] && a[1] == b[2] && a[2] == b[0]) ||
                      (a[0] == b[2] && a[1] == b[0] && a[2] == b[1]);
    ASSERT_TRUE(same) << "triangle " << i;
  }
  EXPECT_DOUBLE_EQ(core::check_mesh(back).volume, core::check_mesh(original).volume);
}

TEST(OpenMeshConversion, FlippedTriangleIsRejectedAndCounted) {
  core::TriangleMesh mesh = test::tetrahedron();
  std::swap(mesh.triangles[3][1], mesh.triangles[3][2]);
  const ToOpenMesh converted = to_openmesh(mesh);
  EXPECT_EQ(converted.rejected_faces, 1u);
  EXPECT_EQ(converted.mesh.n_faces(), 3u);
}

TEST(OpenMeshConversion, ThirdFaceOnAnEdgeIsRejectedAndCounted) {
  core::TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, -1, 0}};
  mesh.triangles = {{0, 1, 2}, {1, 0, 3}, {1, 0, 4}};
  const ToOpenMesh converted = to_openmesh(mesh);
  EXPECT_EQ(converted.rejected_faces, 1u);
  EXPECT_EQ(converted.mesh.n_faces(), 2u);
}

TEST(OpenMeshConversion, RepeatedIndexIsSkipped) {
  core::TriangleMesh mesh = test::tetrahedron();
  mesh.triangles.push_back({1, 1, 2});
  const ToOpenMesh converted = to_openmesh(mesh);
  EXPECT_EQ(converted.skipped_repeated_index, 1u);
  EXPECT_EQ(converted.rejected_faces, 0u);
  EXPECT_EQ(converted.mesh.n_faces(), 4u);
}

TEST(OpenMeshConversion, VertexSharedByTwoShellsIsSplit) {
  const core::TriangleMesh mesh = test::bowtie_tetrahedra();
  ASSERT_EQ(core::check_mesh(mesh).non_manifold_vertices, 1u);
  ToOpenMesh converted = to_openmesh(mesh);
  EXPECT_EQ(converted.rejected_faces, 0u);
  EXPECT_EQ(converted.split_vertices, 1u);
  EXPECT_EQ(converted.mesh.n_faces(), 8u);
  const core::MeshCheck back = core::check_mesh(from_openmesh(converted.mesh));
  EXPECT_TRUE(back.closed_manifold());
  EXPECT_EQ(back.components, 2u);
  EXPECT_DOUBLE_EQ(back.volume, 2.0 / 6.0);
}

}  // namespace
}  // namespace typemerge::mesh::detail
