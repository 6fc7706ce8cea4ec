// The crossing test (core/self_intersections.h): the pair rules on hand-made cases, and the
// whole search against CGAL's own Polygon_mesh_processing::self_intersections on meshes with
// crossings put in on purpose.
#include "core/self_intersections.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

using P = std::array<float, 3>;

TriangleMesh two_triangles(std::vector<P> positions, std::array<std::uint32_t, 3> a,
                           std::array<std::uint32_t, 3> b) {
  TriangleMesh mesh;
  mesh.positions = std::move(positions);
  mesh.normals.assign(mesh.positions.size(), {0, 0, 0});
  mesh.triangles = {a, b};
  return mesh;
}

TEST(SelfIntersections, DisjointAndCrossingTriangles) {
  // A horizontal triangle and a vertical one through its middle.
  auto crossing = two_triangles(
      {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {1, 1, -1}, {1, 1, 1}, {2, 0.5f, 0}}, {0, 1, 2}, {3, 4, 5});
  EXPECT_TRUE(triangles_intersect(crossing, 0, 1));
  EXPECT_EQ(find_self_intersections(crossing).pairs.size(), 1u);
  // The same one lifted above the plane: no common point.
  auto apart = crossing;
  for (std::size_t v = 3; v < 6; ++v) apart.positions[v][2] += 1.5f;
  EXPECT_FALSE(triangles_intersect(apart, 0, 1));
  EXPECT_TRUE(find_self_intersections(apart).pairs.empty());
  // Touching at a point without sharing a vertex index still counts (a solid's surface does
  // not touch itself).
  auto touching = two_triangles({{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {1, 1, 0}, {1, 1, 1}, {2, 1, 1}},
                                {0, 1, 2}, {3, 4, 5});
  EXPECT_TRUE(triangles_intersect(touching, 0, 1));
}

TEST(SelfIntersections, SharedVertexCountsOnlyWhenTheyMeetElsewhere) {
  // Two triangles fanned around vertex 0 at an angle: they meet only there.
  auto fan =
      two_triangles({{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 2}, {2, 0, 1}}, {0, 1, 2}, {0, 3, 4});
  EXPECT_FALSE(triangles_intersect(fan, 0, 1));
  // The second one's far edge dips through the first.
  auto pierced = two_triangles({{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0.5f, 0.5f, -1}, {0.5f, 0.5f, 1}},
                               {0, 1, 2}, {0, 3, 4});
  EXPECT_TRUE(triangles_intersect(pierced, 0, 1));
}

TEST(SelfIntersections, SharedEdgeCountsOnlyWhenFoldedOntoItself) {
  const std::vector<P> base = {{0, 0, 0}, {2, 0, 0}, {1, 1, 0}};
  // Flat, on opposite sides of the edge (0, 1): a plain mesh edge.
  auto flat = two_triangles(base, {0, 1, 2}, {1, 0, 3});
  flat.positions.push_back({1, -1, 0});
  flat.normals.push_back({0, 0, 0});
  EXPECT_FALSE(triangles_intersect(flat, 0, 1));
  // Bent: still fine.
  auto bent = flat;
  bent.positions[3] = {1, -1, 1};
  EXPECT_FALSE(triangles_intersect(bent, 0, 1));
  // Folded flat onto the same side: they overlap.
  auto folded = flat;
  folded.positions[3] = {1, 0.5f, 0};
  EXPECT_TRUE(triangles_intersect(folded, 0, 1));
  // The same triangle twice.
  auto twice = two_triangles(base, {0, 1, 2}, {2, 1, 0});
  EXPECT_TRUE(triangles_intersect(twice, 0, 1));
}

TEST(SelfIntersections, DegenerateTrianglesAreCountedApart) {
  auto mesh = two_triangles({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}}, {0, 1, 2}, {0, 1, 3});
  const auto found = find_self_intersections(mesh);
  EXPECT_EQ(found.degenerate_triangles, 1u);
  EXPECT_TRUE(found.pairs.empty());
}

// CGAL's reference answer for a mesh whose triangles make a valid halfedge structure.
std::set<std::array<std::uint32_t, 2>> cgal_pairs(const TriangleMesh& mesh) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Surface = CGAL::Surface_mesh<Kernel::Point_3>;
  Surface surface;
  for (const auto& p : mesh.positions) surface.add_vertex(Kernel::Point_3(p[0], p[1], p[2]));
  for (const auto& t : mesh.triangles) {
    const auto f = surface.add_face(Surface::Vertex_index(t[0]), Surface::Vertex_index(t[1]),
                                    Surface::Vertex_index(t[2]));
    EXPECT_TRUE(f.is_valid());
  }
  std::vector<std::pair<Surface::Face_index, Surface::Face_index>> found;
  CGAL::Polygon_mesh_processing::self_intersections(surface, std::back_inserter(found));
  std::set<std::array<std::uint32_t, 2>> pairs;
  for (const auto& [f, g] : found) {
    const auto a = static_cast<std::uint32_t>(f.idx());
    const auto b = static_cast<std::uint32_t>(g.idx());
    pairs.insert({std::min(a, b), std::max(a, b)});
  }
  return pairs;
}

TEST(SelfIntersections, MarchingCubesSurfacesHaveNone) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const TriangleMesh mesh = extract_isosurface(test::noise_volume(14, 12, 10, seed), 0.5f);
    ASSERT_FALSE(mesh.empty());
    const auto found = find_self_intersections(mesh);
    EXPECT_TRUE(found.pairs.empty()) << "seed " << seed;
    EXPECT_TRUE(cgal_pairs(mesh).empty()) << "seed " << seed;
  }
}

TEST(SelfIntersections, AgreesWithCgalOnMeshesWithCrossingsPutIn) {
  // Marching-cubes surfaces of noise with random vertices pushed up to 1.5 voxels: many
  // crossings of every kind (shared edge, shared vertex, apart), found by both searches.
  std::size_t total = 0;
  for (unsigned seed : {4u, 5u, 6u, 7u}) {
    TriangleMesh mesh = extract_isosurface(test::noise_volume(12, 12, 10, seed), 0.5f);
    std::mt19937 random(seed);
    std::uniform_real_distribution<float> push(-1.5f, 1.5f);
    for (std::size_t v = 0; v < mesh.positions.size(); v += 7) {
      for (float& x : mesh.positions[v]) x += push(random);
    }
    const auto found = find_self_intersections(mesh);
    std::set<std::array<std::uint32_t, 2>> ours(found.pairs.begin(), found.pairs.end());
    EXPECT_EQ(ours.size(), found.pairs.size()) << "a pair listed twice";
    auto reference = cgal_pairs(mesh);
    // CGAL lists a degenerate face as a pair with itself; we count those apart.
    std::size_t reference_degenerate = 0;
    for (auto it = reference.begin(); it != reference.end();) {
      if ((*it)[0] == (*it)[1]) {
        ++reference_degenerate;
        it = reference.erase(it);
      } else {
        ++it;
      }
    }
    EXPECT_EQ(ours, reference) << "seed " << seed;
    // The library broad phase finds the same (the grid is the default).
    EXPECT_EQ(detail::find_self_intersections_by(mesh, 0, {}, true).pairs, found.pairs);
    EXPECT_EQ(found.degenerate_triangles, reference_degenerate);
    total += ours.size();
    // Restricted to flagged triangles: exactly the pairs with a flagged member.
    std::vector<std::uint8_t> flagged(mesh.triangles.size());
    for (std::size_t t = 0; t < flagged.size(); t += 3) flagged[t] = 1;
    std::set<std::array<std::uint32_t, 2>> expected;
    for (const auto& pair : ours) {
      if (flagged[pair[0]] != 0 || flagged[pair[1]] != 0) expected.insert(pair);
    }
    const auto restricted = find_self_intersections(mesh, 0, flagged);
    const std::set<std::array<std::uint32_t, 2>> restricted_set(restricted.pairs.begin(),
                                                                restricted.pairs.end());
    EXPECT_EQ(restricted_set, expected);
    EXPECT_EQ(restricted.pairs.size(), expected.size()) << "a pair listed twice";
    EXPECT_EQ(detail::find_self_intersections_by(mesh, 0, flagged, true).pairs, restricted.pairs);
    // A bounded search stops early and says so.
    if (ours.size() > 3) {
      const auto bounded = find_self_intersections(mesh, 3);
      EXPECT_TRUE(bounded.truncated);
      EXPECT_EQ(bounded.pairs.size(), 3u);
    }
  }
  EXPECT_GT(total, 50u) << "the perturbation should have made crossings to compare";
}

// One triangle a hundred times the others' size (a decimated or hand-made mesh): too uneven for
// the grid, which hands over to CGAL's box intersection; the pairs are still CGAL's own.
TEST(SelfIntersections, UnevenTriangleSizesGiveTheSamePairs) {
  TriangleMesh mesh = extract_isosurface(test::noise_volume(12, 12, 10, 8), 0.5f);
  const auto base = static_cast<std::uint32_t>(mesh.positions.size());
  for (const std::array<float, 3>& p :
       {std::array<float, 3>{-300, -300, 4.3f}, std::array<float, 3>{300, -300, 4.6f},
        std::array<float, 3>{0, 300, 4.4f}}) {
    mesh.positions.push_back(p);
    mesh.normals.push_back({0, 0, 0});
  }
  mesh.triangles.push_back({base, base + 1, base + 2});  // a sheet through the whole surface
  const auto found = find_self_intersections(mesh);
  const std::set<std::array<std::uint32_t, 2>> ours(found.pairs.begin(), found.pairs.end());
  EXPECT_EQ(ours, cgal_pairs(mesh));
  EXPECT_GT(ours.size(), 20u);
  // Marching cubes' own triangles do not cross: every pair has the sheet in it.
  for (const auto& pair : ours) EXPECT_EQ(pair[1], mesh.triangles.size() - 1);
}

}  // namespace
}  // namespace typemerge::core
