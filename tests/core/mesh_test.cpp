// Tests of to_patient: positions by the affine map, normals by its inverse transpose, winding
// flipped for mirroring maps.
#include "core/mesh.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/mesh_checks.h"

namespace typemerge::core {
namespace {

TriangleMesh unit_tetrahedron() {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const float s = 1.0f / std::sqrt(3.0f);
  m.normals = {{-s, -s, -s}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

TEST(ToPatient, MapsPositionsWithTheAffineMap) {
  TriangleMesh m = unit_tetrahedron();
  IndexToPatient g;
  g.origin = {10, 20, 30};
  g.axes = {{{0.5, 0, 0}, {0, 0.5, 0}, {0, 0.1, 2.0}}};  // tilted slices: shear in y
  to_patient(m, g);
  EXPECT_FLOAT_EQ(m.positions[0][0], 10.0f);
  EXPECT_FLOAT_EQ(m.positions[1][0], 10.5f);
  EXPECT_FLOAT_EQ(m.positions[3][1], 20.1f);
  EXPECT_FLOAT_EQ(m.positions[3][2], 32.0f);
  EXPECT_NEAR(check_mesh(m).volume, g.determinant() / 6.0, 1e-6);
}

TEST(ToPatient, NormalsStayPerpendicularUnderAnisotropicSpacing) {
  // The plane x + y = 1 has normal (1, 1, 0) in index space. With spacing (2, 1, 1) it becomes
  // X/2 + Y = 1, normal (0.5, 1, 0): the inverse transpose, not the map itself.
  TriangleMesh m;
  m.positions = {{1, 0, 0}, {0, 1, 0}, {0, 1, 1}};
  const float s = 1.0f / std::sqrt(2.0f);
  m.normals = {{s, s, 0}, {s, s, 0}, {s, s, 0}};
  m.triangles = {{0, 1, 2}};
  IndexToPatient g;
  g.axes = {{{2, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  to_patient(m, g);
  const float l = std::sqrt(1.25f);
  EXPECT_NEAR(m.normals[0][0], 0.5f / l, 1e-6);
  EXPECT_NEAR(m.normals[0][1], 1.0f / l, 1e-6);
  EXPECT_NEAR(m.normals[0][2], 0.0f, 1e-6);
  // The normal is perpendicular to the mapped surface.
  const auto& p = m.positions;
  const float d[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
  EXPECT_NEAR(d[0] * m.normals[0][0] + d[1] * m.normals[0][1] + d[2] * m.normals[0][2], 0.0f, 1e-6);
}

TEST(ToPatient, MirroringMapKeepsTheSurfaceOutward) {
  TriangleMesh m = unit_tetrahedron();
  IndexToPatient g;
  g.axes = {{{-0.7, 0, 0}, {0, 0.5, 0}, {0, 0, 2.0}}};  // x flipped: determinant < 0
  ASSERT_LT(g.determinant(), 0.0);
  to_patient(m, g);
  const MeshCheck c = check_mesh(m);
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_NEAR(c.volume, -g.determinant() / 6.0, 1e-6);
  // The normal of vertex 1 was +x (outward, away from the tetrahedron); the tetrahedron now
  // lies at negative X, so outward is −X.
  EXPECT_NEAR(m.normals[1][0], -1.0f, 1e-6);
}

}  // namespace
}  // namespace typemerge::core
