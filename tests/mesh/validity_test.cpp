// Tests of check_validity (a hole, a flipped triangle, a non-manifold edge are each named)
// and repair_mesh (exact collapses of zero-length edges, dropped repeated-index triangles,
// removed unused vertices).
#include "mesh/validity.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>

#include "mesh/test_surfaces.h"

namespace typemerge::mesh {
namespace {

core::TriangleMesh small_sphere() { return test::sphere(20, {9.4, 9.6, 9.3, 6.0}); }

bool mentions(const std::vector<std::string>& lines, const std::string& word) {
  for (const auto& line : lines) {
    if (line.find(word) != std::string::npos) return true;
  }
  return false;
}

TEST(Validity, ExtractedSphereIsValid) {
  const Validity v = check_validity(small_sphere());
  EXPECT_TRUE(v.valid());
  EXPECT_TRUE(v.problems().empty());
  EXPECT_EQ(v.check.euler_characteristic, 2);
}

TEST(Validity, FlagsAHole) {
  core::TriangleMesh mesh = small_sphere();
  mesh.triangles.erase(mesh.triangles.begin() + 17);
  const Validity v = check_validity(mesh);
  EXPECT_FALSE(v.valid());
  EXPECT_FALSE(v.closed());
  EXPECT_TRUE(v.manifold());
  EXPECT_TRUE(v.oriented());
  EXPECT_EQ(v.check.boundary_edges, 3u);
  EXPECT_TRUE(mentions(v.problems(), "boundary"));
}

TEST(Validity, FlagsAFlippedTriangle) {
  core::TriangleMesh mesh = small_sphere();
  std::swap(mesh.triangles[5][1], mesh.triangles[5][2]);
  const Validity v = check_validity(mesh);
  EXPECT_FALSE(v.valid());
  EXPECT_TRUE(v.closed());
  EXPECT_FALSE(v.oriented());
  EXPECT_EQ(v.check.inconsistent_edges, 3u);
  EXPECT_TRUE(mentions(v.problems(), "oriented"));
}

TEST(Validity, FlagsANonManifoldEdge) {
  core::TriangleMesh mesh = small_sphere();
  // A fin: a new triangle on an existing edge.
  const auto t = mesh.triangles[0];
  mesh.positions.push_back({0.0f, 0.0f, 0.0f});
  mesh.triangles.push_back({t[0], t[1], static_cast<std::uint32_t>(mesh.positions.size() - 1)});
  const Validity v = check_validity(mesh);
  EXPECT_FALSE(v.valid());
  EXPECT_FALSE(v.manifold());
  EXPECT_EQ(v.check.non_manifold_edges, 1u);
  EXPECT_TRUE(mentions(v.problems(), "more than two"));
}

// Splits vertex v of a closed manifold mesh into v and a coincident copy m, taking the
// triangles of half its ring to m and closing the slit with two zero-area triangles
// (m, r_j, v) and (v, r_0, m) — the inverse of collapsing the zero-length edge v–m.
void split_vertex(core::TriangleMesh& mesh, std::uint32_t v) {
  std::map<std::uint32_t, std::pair<std::uint32_t, std::size_t>> next;  // a → (b, triangle)
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
      if (t[k] == v) next[t[(k + 1) % 3]] = {t[(k + 2) % 3], i};
    }
  }
  ASSERT_GE(next.size(), 4u);
  const auto m = static_cast<std::uint32_t>(mesh.positions.size());
  mesh.positions.push_back(mesh.positions[v]);
  const std::uint32_t r0 = next.begin()->first;
  std::uint32_t r = r0;
  for (std::size_t step = 0; step < next.size() / 2; ++step) {
    auto& t = mesh.triangles[next[r].second];
    for (auto& index : t) {
      if (index == v) index = m;
    }
    r = next[r].first;
  }
  // m now has the fan r0 → … → r (= r_j); v keeps r → … → r0.
  mesh.triangles.push_back({m, r, v});
  mesh.triangles.push_back({v, r0, m});
}

TEST(Repair, CollapsesZeroLengthEdgesExactly) {
  const core::TriangleMesh original = small_sphere();
  core::TriangleMesh mesh = original;
  split_vertex(mesh, 10);
  split_vertex(mesh, 200);
  const Validity broken = check_validity(mesh);
  ASSERT_EQ(broken.check.degenerate_triangles, 4u);
  ASSERT_EQ(broken.check.boundary_edges, 0u);
  ASSERT_EQ(broken.check.inconsistent_edges, 0u);
  // Plus a triangle with a repeated index and an unused vertex.
  mesh.triangles.push_back({3, 3, 4});
  mesh.positions.push_back({100.0f, 100.0f, 100.0f});

  const RepairReport report = repair_mesh(mesh);

  EXPECT_EQ(report.removed_repeated_index_triangles, 1u);
  EXPECT_EQ(report.collapsed_zero_length_edges, 2u);
  EXPECT_EQ(report.removed_collapsed_triangles, 4u);
  EXPECT_EQ(report.removed_unreferenced_vertices, 3u);  // two merged copies, one unused
  EXPECT_EQ(report.remaining_degenerate_triangles, 0u);
  EXPECT_TRUE(report.validity.valid());
  EXPECT_EQ(mesh.triangles.size(), original.triangles.size());
  EXPECT_EQ(mesh.positions, original.positions);  // nothing moved, order kept
  EXPECT_EQ(report.validity.check.volume, check_validity(original).check.volume);
}

TEST(Repair, ValidMeshIsUntouched) {
  core::TriangleMesh mesh = small_sphere();
  const core::TriangleMesh original = mesh;
  const RepairReport report = repair_mesh(mesh);
  EXPECT_EQ(report.collapsed_zero_length_edges + report.removed_repeated_index_triangles +
                report.removed_unreferenced_vertices,
            0u);
  EXPECT_EQ(mesh.triangles, original.triangles);
  EXPECT_EQ(mesh.positions, original.positions);
  EXPECT_EQ(mesh.normals, original.normals);
}

TEST(Repair, CountsNeedlesItLeaves) {
  // A needle (2 on the segment 0–1) in an otherwise open fan: repair leaves it and says so.
  core::TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {2, 0, 0}, {1, 0, 0}, {1, 1, 0}};
  mesh.triangles = {{0, 1, 2}, {1, 0, 3}};
  const RepairReport report = repair_mesh(mesh);
  EXPECT_EQ(report.remaining_degenerate_triangles, 1u);
  EXPECT_EQ(mesh.triangles.size(), 2u);
}

TEST(RemoveUnreferencedVertices, RenumbersTrianglesAndNormals) {
  core::TriangleMesh mesh;
  mesh.positions = {{9, 9, 9}, {0, 0, 0}, {1, 0, 0}, {8, 8, 8}, {0, 1, 0}};
  mesh.normals = {{0, 0, 9}, {0, 0, 1}, {0, 0, 2}, {0, 0, 8}, {0, 0, 4}};
  mesh.triangles = {{1, 2, 4}};
  EXPECT_EQ(remove_unreferenced_vertices(mesh), 2u);
  const std::vector<std::array<float, 3>> positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<std::array<float, 3>> normals = {{0, 0, 1}, {0, 0, 2}, {0, 0, 4}};
  const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}};
  EXPECT_EQ(mesh.positions, positions);
  EXPECT_EQ(mesh.normals, normals);
  EXPECT_EQ(mesh.triangles, triangles);
}

}  // namespace
}  // namespace typemerge::mesh
