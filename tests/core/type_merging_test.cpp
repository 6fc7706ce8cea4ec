// Tests of merge_types / extract_type_merged, up the oracle ladder: planes of every table
// family (types 0, 1, 2, hexagons, generic) where the merged mesh must stay exactly on the plane,
// keep its border, area and orientation; closed smooth surfaces (spheres, torus) for topology,
// Hausdorff distance and the spec's reduction band; random noise for watertightness and
// manifoldness under many ambiguities; options and determinism.
#include "core/type_merging.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/self_intersections.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

using test::noise_volume;
using test::sample_volume;
using test::sphere_volume;

constexpr ExtractOptions kOpen{.close_borders = false};
constexpr ExtractOptions kClosed{.close_borders = true};

struct Extracted {
  TriangleMesh mc;
  TriangleMesh tm;
  MergeStats stats;
};

Extracted extract_both(const Volume& volume, float iso, const ExtractOptions& extract,
                       const MergeOptions& options = {}) {
  Extracted out;
  std::vector<BoundaryCube> cubes;
  ExtractOptions with_cubes = extract;
  with_cubes.cubes = &cubes;
  out.mc = extract_isosurface(volume, iso, with_cubes);
  out.tm = out.mc;
  merge_types(out.tm, cubes, options, &out.stats);
  return out;
}

double ratio(const Extracted& e) {
  return static_cast<double>(e.tm.triangles.size()) / static_cast<double>(e.mc.triangles.size());
}

std::array<double, 3> triangle_normal(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& t) {
  const auto& p0 = mesh.positions[t[0]];
  const auto& p1 = mesh.positions[t[1]];
  const auto& p2 = mesh.positions[t[2]];
  const std::array<double, 3> a{double{p1[0]} - p0[0], double{p1[1]} - p0[1], double{p1[2]} - p0[2]};
  const std::array<double, 3> b{double{p2[0]} - p0[0], double{p2[1]} - p0[1], double{p2[2]} - p0[2]};
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// Largest distance from a vertex of `from` to the surface `to` (brute force over a uniform grid
// of triangle buckets; exact within `reach`, which must exceed the answer).
double max_vertex_to_mesh_distance(const TriangleMesh& from, const TriangleMesh& to,
                                   double reach = 2.0) {
  std::array<double, 3> lo{1e30, 1e30, 1e30};
  std::array<double, 3> hi{-1e30, -1e30, -1e30};
  for (const auto& p : to.positions) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], double{p[a]} - reach);
      hi[a] = std::max(hi[a], double{p[a]} + reach);
    }
  }
  const double cell = reach;
  std::array<int, 3> dims{};
  for (int a = 0; a < 3; ++a) dims[a] = static_cast<int>((hi[a] - lo[a]) / cell) + 1;
  auto cell_of = [&](double v, int a) {
    return std::clamp(static_cast<int>((v - lo[a]) / cell), 0, dims[a] - 1);
  };
  std::vector<std::vector<std::uint32_t>> buckets(
      static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
      static_cast<std::size_t>(dims[2]));
  auto bucket = [&](int x, int y, int z) -> std::vector<std::uint32_t>& {
    return buckets[static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z))];
  };
  for (std::uint32_t t = 0; t < to.triangles.size(); ++t) {
    std::array<int, 3> c0{};
    std::array<int, 3> c1{};
    for (int a = 0; a < 3; ++a) {
      double mn = 1e30;
      double mx = -1e30;
      for (auto v : to.triangles[t]) {
        mn = std::min(mn, double{to.positions[v][a]});
        mx = std::max(mx, double{to.positions[v][a]});
      }
      c0[a] = cell_of(mn - reach, a);
      c1[a] = cell_of(mx + reach, a);
    }
    for (int z = c0[2]; z <= c1[2]; ++z) {
      for (int y = c0[1]; y <= c1[1]; ++y) {
        for (int x = c0[0]; x <= c1[0]; ++x) bucket(x, y, z).push_back(t);
      }
    }
  }
  auto p3 = [](const std::array<float, 3>& p) { return std::array<double, 3>{p[0], p[1], p[2]}; };
  double worst = 0.0;
  for (const auto& p : from.positions) {
    const auto& list = bucket(cell_of(p[0], 0), cell_of(p[1], 1), cell_of(p[2], 2));
    double best = reach * reach;
    for (std::uint32_t t : list) {
      const auto& tri = to.triangles[t];
      best = std::min(best, detail::point_triangle_distance_squared(
                                p3(p), p3(to.positions[tri[0]]), p3(to.positions[tri[1]]),
                                p3(to.positions[tri[2]])));
    }
    worst = std::max(worst, std::sqrt(best));
  }
  return worst;
}

// Topology and validity the merge must keep, for closed or open MC meshes.
void expect_same_topology(const Extracted& e) {
  const MeshCheck mc = check_mesh(e.mc);
  const MeshCheck tm = check_mesh(e.tm);
  EXPECT_EQ(tm.non_manifold_edges, 0u);
  EXPECT_EQ(tm.non_manifold_vertices, 0u);
  EXPECT_EQ(tm.inconsistent_edges, 0u);
  EXPECT_EQ(tm.degenerate_triangles, 0u);
  EXPECT_EQ(tm.boundary_edges, mc.boundary_edges);
  EXPECT_EQ(tm.euler_characteristic, mc.euler_characteristic);
  EXPECT_EQ(tm.components, mc.components);
  EXPECT_EQ(tm.vertices, e.tm.positions.size());  // compacted: no unused vertex
  EXPECT_EQ(e.stats.triangles_before, e.mc.triangles.size());
  EXPECT_EQ(e.stats.triangles_after, e.tm.triangles.size());
  EXPECT_EQ(e.stats.slivers_left, 0u);
  // The crossing guard: no two triangles cross (exact predicates), as in marching cubes.
  EXPECT_TRUE(find_self_intersections(e.tm).pairs.empty());
  EXPECT_TRUE(find_self_intersections(e.mc).pairs.empty());
}

// ---- Planes --------------------------------------------------------------------------------

struct PlaneCase {
  const char* name;
  std::array<double, 3> normal;  // inside: normal·p < offset
  double offset;
  double max_ratio;  // TM / MC triangles must not exceed this
};

// Families of spec §4.6 (ratios there: checked, cap 4: 22 %, 24 %, 64 %, 64 %, 52 %, 100 %,
// 86 %). Our run cap is 6, so types 0/1 do better than with 4.
constexpr PlaneCase kPlanes[] = {
    {"type 0, z", {0, 0, 1}, 7.37, 0.30},
    {"type 0, x", {1, 0, 0}, 7.61, 0.30},
    {"type 1, (0,1,1)", {0, 1, 1}, 14.3, 0.35},
    {"type 1, (1,-1,0)", {1, -1, 0}, 0.41, 0.35},
    {"type 2, (1,1,2)", {1, 1, 2}, 20.3, 0.75},
    {"type 2, (2,1,-1)", {2, 1, -1}, 8.3, 0.75},
    {"type 2, (1,-2,1)", {1, -2, 1}, 0.3, 0.75},
    {"hexagon, (1,1,-1)", {1, 1, -1}, 7.4, 0.65},
    {"hexagon, (1,1,1)", {1, 1, 1}, 22.6, 0.65},
    {"mixed, (3,1,1)", {3, 1, 1}, 30.2, 0.6},
    {"generic, (1,2,3)", {1, 2, 3}, 40.3, 0.6},  // type 3 only (types 0–2: 100 %)
    {"generic, (0.31,0.52,0.79)", {0.31, 0.52, 0.79}, 12.1, 0.6},
};

TEST(TypeMerging, PlanesStayExactlyPlanarWithTheirBorderAndArea) {
  for (const PlaneCase& plane : kPlanes) {
    SCOPED_TRACE(plane.name);
    const auto& n = plane.normal;
    const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const Volume volume = sample_volume(17, 16, 15, [&](double x, double y, double z) {
      return (plane.offset - (n[0] * x + n[1] * y + n[2] * z)) / length;
    });
    const Extracted e = extract_both(volume, 0.0f, kOpen);
    ASSERT_FALSE(e.mc.empty());
    expect_same_topology(e);

    // Every vertex on the plane: merged vertices are MC vertices that did not move, so they
    // are as close as the MC vertices are (float rounding, and kEdgeMargin where the plane
    // passes within 1e-3 of a sample).
    auto max_deviation = [&](const TriangleMesh& mesh) {
      double worst = 0.0;
      for (const auto& p : mesh.positions) {
        const double d = (n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - plane.offset) / length;
        worst = std::max(worst, std::abs(d));
      }
      return worst;
    };
    EXPECT_LE(max_deviation(e.mc), 1.5 * kEdgeMargin);
    EXPECT_LE(max_deviation(e.tm), max_deviation(e.mc));
    for (const auto& p : e.tm.positions) {
      ASSERT_NE(std::find(e.mc.positions.begin(), e.mc.positions.end(), p), e.mc.positions.end());
    }
    // No fold-over: every triangle faces outward (+n). On a plane the merged mesh covers the
    // same region with the same border, so its area is the MC area.
    std::size_t folded = 0;
    for (const auto& t : e.tm.triangles) {
      const auto tn = triangle_normal(e.tm, t);
      if (!((tn[0] * n[0] + tn[1] * n[1] + tn[2] * n[2]) / length > 0.0)) ++folded;
    }
    EXPECT_EQ(folded, 0u);
    EXPECT_NEAR(check_mesh(e.tm).area / check_mesh(e.mc).area, 1.0, 1e-5);
    std::printf(
        "[ plane    ] %-28s MC %5zu -> TM %5zu triangles (%.1f %%), merges %zu/%zu/%zu, "
        "collapses %zu/%zu, rejected boundary %zu link %zu normal %zu gradient %zu distance %zu, "
        "abandoned %zu, slivers removed %zu\n",
        plane.name, e.mc.triangles.size(), e.tm.triangles.size(), 100.0 * ratio(e),
        e.stats.cubes_merged_by_type[0], e.stats.cubes_merged_by_type[1],
        e.stats.cubes_merged_by_type[2], e.stats.collapses_done, e.stats.collapses_tried,
        e.stats.rejected_boundary, e.stats.rejected_link, e.stats.rejected_normal,
        e.stats.rejected_gradient, e.stats.rejected_distance, e.stats.merges_abandoned,
        e.stats.sliver_collapses);
    EXPECT_LE(ratio(e), plane.max_ratio);
  }
}

// With a cap of one cube per run nothing merges, whatever the surface.
TEST(TypeMerging, RunCapOneMergesNothing) {
  const Volume volume = sphere_volume(24, 8.3, 11.2, 11.6, 11.9);
  MergeOptions options;
  options.run_cap = 1;
  options.type3 = false;  // type-3 blocks are not runs
  const Extracted e = extract_both(volume, 0.0f, kClosed, options);
  EXPECT_EQ(e.tm.triangles.size(), e.mc.triangles.size());
  EXPECT_EQ(e.stats.collapses_done, 0u);
}

// The merge counts by direction add up to the merges by type.
// Spec §3.4: a generic plane such as (1,2,3) is orthogonal to no merge direction, so types
// 0–2 leave it as MC made it; type 3 is what reduces it (the planes test above checks that
// the result stays on the plane, unfolded, with its area).
TEST(TypeMerging, Type3ReducesPlanesTheOtherTypesCannot) {
  const Volume volume = sample_volume(17, 16, 15, [](double x, double y, double z) {
    return (40.3 - (x + 2 * y + 3 * z)) / std::sqrt(14.0);
  });
  MergeOptions without;
  without.type3 = false;
  const Extracted plain = extract_both(volume, 0.0f, kOpen, without);
  EXPECT_EQ(plain.tm.triangles.size(), plain.mc.triangles.size());
  EXPECT_EQ(plain.stats.type3_groups, 0u);
  const Extracted e = extract_both(volume, 0.0f, kOpen);
  EXPECT_GT(e.stats.type3_groups, 20u);
  EXPECT_LT(ratio(e), 0.6);
  expect_same_topology(e);
}

TEST(TypeMerging, StatisticsAreConsistent) {
  const Volume volume = sphere_volume(28, 10.3, 13.1, 13.6, 13.3);
  const Extracted e = extract_both(volume, 0.0f, kClosed);
  std::size_t by_type = 0;
  std::size_t by_direction = 0;
  for (auto n : e.stats.cubes_merged_by_type) by_type += n;
  for (auto n : e.stats.merges_by_direction) by_direction += n;
  EXPECT_EQ(by_type, by_direction);
  EXPECT_GT(by_type, 0u);
  EXPECT_LE(e.stats.collapses_done, e.stats.collapses_tried);
  EXPECT_EQ(e.stats.vertices_before, e.mc.positions.size());
  EXPECT_EQ(e.stats.vertices_after, e.tm.positions.size());
}

// ---- Closed smooth surfaces ------------------------------------------------------------------

void check_smooth_closed(const char* name, const Volume& volume, std::int64_t chi,
                         const MergeOptions& options = {}) {
  SCOPED_TRACE(name);
  const Extracted e = extract_both(volume, 0.0f, kClosed, options);
  const MeshCheck tm = check_mesh(e.tm);
  EXPECT_TRUE(tm.closed_manifold());
  EXPECT_EQ(tm.euler_characteristic, chi);
  EXPECT_EQ(tm.components, 1u);
  expect_same_topology(e);
  const double hausdorff = max_vertex_to_mesh_distance(e.mc, e.tm);
  EXPECT_LE(hausdorff, options.epsilon_voxels + 0.1);
  // Collapsing vertices of a convex surface cuts corners, by at most epsilon: measured
  // −2.5 % volume on the R = 10.3 sphere and −2.7 % on the torus (tube radius 4).
  EXPECT_NEAR(tm.volume / check_mesh(e.mc).volume, 1.0, 0.04);
  std::printf(
      "[ closed   ] %-16s MC %6zu -> TM %6zu triangles (%.1f %%), max MC vertex distance "
      "%.3f voxel, merges by type %zu/%zu/%zu (hexagon %zu, minor %zu), collapses %zu/%zu, "
      "rejected link %zu normal %zu gradient %zu distance %zu fan %zu, capped %zu\n",
      name, e.mc.triangles.size(), e.tm.triangles.size(), 100.0 * ratio(e), hausdorff,
      e.stats.cubes_merged_by_type[0], e.stats.cubes_merged_by_type[1],
      e.stats.cubes_merged_by_type[2], e.stats.hexagon_merges, e.stats.minor_merges,
      e.stats.collapses_done, e.stats.collapses_tried, e.stats.rejected_link,
      e.stats.rejected_normal, e.stats.rejected_gradient, e.stats.rejected_distance,
      e.stats.rejected_fan_size, e.stats.runs_capped);
  // Spec §4.6: 55–60 % with the checks on spheres.
  EXPECT_LE(ratio(e), 0.70);
}

TEST(TypeMerging, SpheresKeepTopologyAndStayWithinEpsilon) {
  check_smooth_closed("sphere R=10.3", sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 2);
  check_smooth_closed("sphere R=20.3", sphere_volume(46, 20.3, 22.4, 22.7, 22.2), 2);
}

TEST(TypeMerging, TorusKeepsTopology) {
  const Volume volume = sample_volume(32, 32, 14, [&](double x, double y, double z) {
    const double dx = x - 15.6;
    const double dy = y - 15.3;
    const double dz = z - 6.7;
    const double ring = std::sqrt(dx * dx + dy * dy) - 10.0;
    return 4.0 - std::sqrt(ring * ring + dz * dz);
  });
  check_smooth_closed("torus 10/4", volume, 0);
}

TEST(TypeMerging, HexagonThirdLineAndShortRunsKeepTopology) {
  MergeOptions options;
  options.hexagon_all_lines = true;
  options.run_cap = 3;
  check_smooth_closed("sphere hex3 cap3", sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 2, options);
}

TEST(TypeMerging, SmallerEpsilonIsRespected) {
  MergeOptions options;
  options.epsilon_voxels = 0.2;
  check_smooth_closed("sphere eps 0.2", sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 2, options);
}

// Triangle normals of the merged sphere point away from the centre.
TEST(TypeMerging, SphereHasNoFoldedTriangles) {
  const double c[3] = {22.4, 22.7, 22.2};
  const Extracted e = extract_both(sphere_volume(46, 20.3, c[0], c[1], c[2]), 0.0f, kClosed);
  for (const auto& t : e.tm.triangles) {
    const auto tn = triangle_normal(e.tm, t);
    double centroid[3] = {0, 0, 0};
    for (auto v : t) {
      for (int a = 0; a < 3; ++a) centroid[a] += e.tm.positions[v][a] / 3.0;
    }
    double radial = 0.0;
    for (int a = 0; a < 3; ++a) radial += tn[a] * (centroid[a] - c[a]);
    ASSERT_GT(radial, 0.0);
  }
}

// ---- Noise ----------------------------------------------------------------------------------

TEST(TypeMerging, NoiseStaysWatertightAndManifold) {
  for (unsigned seed = 1; seed <= 40; ++seed) {
    SCOPED_TRACE(seed);
    const Volume volume = noise_volume(11, 10, 9, seed);
    for (const ExtractOptions& extract : {kClosed, kOpen}) {
      const Extracted e = extract_both(volume, 0.5f, extract);
      expect_same_topology(e);
      if (extract.close_borders) {
        EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
      }
    }
  }
}

// A merged surface with boundaries (open borders, classic holes): the same boundary, the
// same non-manifold edges as marching cubes left, the same topology, and nothing new wrong.
void expect_same_open_surface(const MeshCheck& mc, const MeshCheck& tm) {
  EXPECT_EQ(tm.boundary_edges, mc.boundary_edges);
  EXPECT_EQ(tm.non_manifold_edges, mc.non_manifold_edges);
  EXPECT_EQ(tm.inconsistent_edges, 0u);
  EXPECT_EQ(tm.degenerate_triangles, 0u);
  EXPECT_EQ(tm.euler_characteristic, mc.euler_characteristic);
  EXPECT_EQ(tm.components, mc.components);
}

// Classic MC leaves holes on ambiguous faces; merging must keep them exactly (boundary
// vertices never move) and stay manifold.
TEST(TypeMerging, ClassicModeHolesAreKept) {
  constexpr ExtractOptions kClassic{.close_borders = true, .mode = ExtractOptions::Mode::classic};
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE(seed);
    const Extracted e = extract_both(noise_volume(11, 10, 9, seed), 0.5f, kClassic);
    expect_same_open_surface(check_mesh(e.mc), check_mesh(e.tm));
  }
}

// Smooth noise (blurred) has long same-index runs and ambiguities together.
TEST(TypeMerging, BlobsStayWatertightAndManifold) {
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE(seed);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 24.0);
    std::array<std::array<double, 3>, 6> centres{};
    for (auto& c : centres) c = {u(rng), u(rng), u(rng)};
    const Volume volume = sample_volume(24, 24, 24, [&](double x, double y, double z) {
      double f = 0.0;
      for (const auto& c : centres) {
        const double d2 = (x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) + (z - c[2]) * (z - c[2]);
        f += std::exp(-d2 / 18.0);
      }
      return f;
    });
    const Extracted e = extract_both(volume, 0.4f, kClosed);
    expect_same_topology(e);
    EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
    EXPECT_LE(max_vertex_to_mesh_distance(e.mc, e.tm), 0.6);
  }
}

// ---- Determinism and the one-call API ------------------------------------------------------

// One piece (slab_layers = 0) is the whole surface merged in the paper's plain scan order,
// which is what merge_types does; and it is deterministic.
TEST(TypeMerging, OnePieceIsTheWholeSurfaceMergedInScanOrder) {
  const Volume volume = sphere_volume(30, 11.7, 14.1, 14.3, 14.6);
  MergeOptions whole;
  whole.slab_layers = 0;
  const Extracted a = extract_both(volume, 0.0f, kClosed);
  const Extracted b = extract_both(volume, 0.0f, kClosed);
  const TriangleMesh c = extract_type_merged(volume, 0.0f, kClosed, whole);
  EXPECT_EQ(a.tm.triangles, b.tm.triangles);
  EXPECT_EQ(a.tm.positions, b.tm.positions);
  EXPECT_EQ(a.tm.triangles, c.triangles);
  EXPECT_EQ(a.tm.positions, c.positions);
  EXPECT_EQ(a.tm.normals, c.normals);
}

// Volumes for the pieces of extract_type_merged: with pieces of 4 layers every one has several
// pieces and most cubes lie near a seam.
std::vector<Volume> slab_test_volumes() {
  std::vector<Volume> volumes;
  for (unsigned seed = 1; seed <= 4; ++seed) volumes.push_back(noise_volume(11, 10, 13, seed));
  volumes.push_back(sphere_volume(26, 10.3, 12.4, 12.7, 12.2));
  volumes.push_back(sphere_volume(46, 20.3, 22.4, 22.7, 22.2));
  for (unsigned seed = 1; seed <= 3; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 24.0);
    std::array<std::array<double, 3>, 6> centres{};
    for (auto& c : centres) c = {u(rng), u(rng), u(rng)};
    volumes.push_back(sample_volume(24, 24, 24, [&](double x, double y, double z) {
      double f = 0.0;
      for (const auto& c : centres) {
        const double d2 = (x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) + (z - c[2]) * (z - c[2]);
        f += std::exp(-d2 / 18.0);
      }
      return f - 0.4;
    }));
  }
  return volumes;
}

// extract_type_merged in pieces of slab_layers cube layers, each merged alone with its seams
// fixed, then stitched: the same guarantees as one piece (closed, manifold, MC's topology,
// every MC vertex within epsilon), the MC counts in the statistics, and one output for any
// thread count. Pieces of one layer are the extreme case: every vertex is on a seam.
TEST(TypeMerging, PiecesStitchIntoTheSameSurfaceForAnyThreadCount) {
  const std::vector<Volume> volumes = slab_test_volumes();
  for (std::size_t i = 0; i < volumes.size(); ++i) {
    SCOPED_TRACE(i);
    const float iso = i < 4 ? 0.5f : 0.0f;
    AmbiguityStats mc_ambiguity;
    ExtractOptions extract = kClosed;
    extract.stats = &mc_ambiguity;
    const TriangleMesh mc = extract_isosurface(volumes[i], iso, extract);
    for (unsigned slab_layers : {1u, 4u, 16u}) {
      SCOPED_TRACE(slab_layers);
      MergeOptions options;
      options.slab_layers = slab_layers;
      Extracted one{mc, {}, {}};
      AmbiguityStats ambiguity;
      extract.stats = &ambiguity;
      one.tm = extract_type_merged(volumes[i], iso, extract, options, &one.stats);
      EXPECT_EQ(ambiguity.boundary_cubes, mc_ambiguity.boundary_cubes);
      EXPECT_EQ(ambiguity.cubes_with_ambiguous_faces, mc_ambiguity.cubes_with_ambiguous_faces);
      EXPECT_EQ(ambiguity.joined_faces, mc_ambiguity.joined_faces);
      expect_same_topology(one);
      EXPECT_TRUE(check_mesh(one.tm).closed_manifold());
      EXPECT_EQ(one.stats.vertices_before, mc.positions.size());
      EXPECT_LE(max_vertex_to_mesh_distance(mc, one.tm), options.epsilon_voxels + 1e-6);
      if (slab_layers >= 4) {
        EXPECT_LT(one.tm.triangles.size(), mc.triangles.size());
      }
      for (unsigned threads : {2u, 3u}) {
        SCOPED_TRACE(threads);
        options.threads = threads;
        MergeStats stats;
        const TriangleMesh many = extract_type_merged(volumes[i], iso, kClosed, options, &stats);
        EXPECT_EQ(many.triangles, one.tm.triangles);
        EXPECT_EQ(many.positions, one.tm.positions);
        EXPECT_EQ(many.normals, one.tm.normals);
        EXPECT_EQ(stats.collapses_done, one.stats.collapses_done);
      }
    }
  }
}

// Thin noisy spherical shells (two sheets about a voxel apart, as cortex is) on a grid of
// thick slices (0.7 × 0.7 × 3 mm), merged with loosened checks (larger ε, runs and normal
// limits) so that stretched fans reach through the other sheet: without the guard they cross,
// with it no pair is left, in patient millimetres as written, for any thread count, with
// marching cubes' topology.
TEST(TypeMerging, CrossingGuardRemovesTheCrossingsStretchedFansMake) {
  MergeOptions loose;
  loose.epsilon_voxels = 1.5;
  loose.max_normal_change_deg = 89;
  loose.max_normal_to_gradient_deg = 89;
  loose.run_cap = 16;
  IndexToPatient geometry;
  geometry.axes = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 3.0}}};
  std::size_t unguarded = 0;
  std::size_t rounds = 0;
  for (double thickness : {0.8, 1.1}) {
    for (unsigned seed = 1; seed <= 6; ++seed) {
      SCOPED_TRACE(testing::Message() << "thickness " << thickness << " seed " << seed);
      std::mt19937 random(seed);
      std::uniform_real_distribution<double> wobble(-0.3, 0.3);
      const double radius = 9 + seed * 0.37;
      Volume volume = sample_volume(32, 32, 32, [&](double x, double y, double z) {
        const double r = std::sqrt((x - 15.5) * (x - 15.5) + (y - 15.7) * (y - 15.7) +
                                   (z - 15.3) * (z - 15.3));
        return thickness / 2 - std::abs(r - radius) + wobble(random);
      });
      volume.set_geometry(geometry);
      MergeOptions off = loose;
      off.prevent_crossings = false;
      TriangleMesh plain = extract_type_merged(volume, 0.0f, kClosed, off);
      to_patient(plain, geometry);
      unguarded += find_self_intersections(plain).pairs.size();

      MergeStats stats;
      Extracted guarded{extract_isosurface(volume, 0.0f, kClosed), {}, {}};
      guarded.tm = extract_type_merged(volume, 0.0f, kClosed, loose, &stats);
      guarded.stats = stats;
      rounds += stats.crossing_rounds;
      EXPECT_EQ(stats.crossings_left, 0u);
      TriangleMesh written = guarded.tm;
      to_patient(written, geometry);
      EXPECT_TRUE(find_self_intersections(written).pairs.empty());
      EXPECT_TRUE(check_mesh(guarded.tm).closed_manifold());
      EXPECT_EQ(check_mesh(guarded.tm).euler_characteristic,
                check_mesh(guarded.mc).euler_characteristic);
      EXPECT_EQ(check_mesh(guarded.tm).components, check_mesh(guarded.mc).components);
      MergeOptions two = loose;
      two.threads = 2;
      EXPECT_EQ(extract_type_merged(volume, 0.0f, kClosed, two).triangles, guarded.tm.triangles);
    }
  }
  EXPECT_GT(unguarded, 10u) << "the loosened merge should have made crossings to remove";
  EXPECT_GT(rounds, 0u);
}

// Pieces where the surface is open (borders left open, classic mode's holes): boundaries stay
// exactly as marching cubes leaves them, also where they cross a seam.
TEST(TypeMerging, PiecesKeepOpenBordersAndHoles) {
  constexpr ExtractOptions kClassic{.close_borders = true, .mode = ExtractOptions::Mode::classic};
  MergeOptions options;
  options.slab_layers = 3;
  for (const ExtractOptions& extract : {kOpen, kClassic}) {
    for (unsigned seed = 1; seed <= 6; ++seed) {
      SCOPED_TRACE(seed);
      const Volume volume = noise_volume(11, 10, 13, seed);
      const MeshCheck mc = check_mesh(extract_isosurface(volume, 0.5f, extract));
      EXPECT_GT(mc.boundary_edges, 0u);
      expect_same_open_surface(mc, check_mesh(extract_type_merged(volume, 0.5f, extract, options)));
    }
  }
}

// The class bound: no limit merges at least as much on the sphere, and a tiny bound still
// keeps every guarantee.
TEST(TypeMerging, ClassBoundKeepsGuarantees) {
  MergeOptions options;
  const Volume volume = sphere_volume(26, 10.3, 12.4, 12.7, 12.2);
  options.max_class_vertices = 2;
  const Extracted bounded = extract_both(volume, 0.0f, kClosed, options);
  options.max_class_vertices = 0;
  const Extracted unbounded = extract_both(volume, 0.0f, kClosed, options);
  expect_same_topology(bounded);
  EXPECT_TRUE(check_mesh(bounded.tm).closed_manifold());
  EXPECT_LE(max_vertex_to_mesh_distance(bounded.mc, bounded.tm), options.epsilon_voxels + 1e-6);
  EXPECT_GT(bounded.stats.rejected_class_size, 0u);
  EXPECT_EQ(unbounded.stats.rejected_class_size, 0u);
  EXPECT_GE(bounded.tm.triangles.size(), unbounded.tm.triangles.size());
}

TEST(TypeMerging, EmptyVolumeGivesEmptyMesh) {
  const Volume volume = sample_volume(5, 5, 5, [](double, double, double) { return 0.0; });
  MergeStats stats;
  const TriangleMesh mesh = extract_type_merged(volume, 1.0f, kClosed, {}, &stats);
  EXPECT_TRUE(mesh.empty());
  EXPECT_EQ(stats.triangles_before, 0u);
}

// ---- Point–triangle distance (the Hausdorff oracle) -----------------------------------------

TEST(TypeMerging, PointTriangleDistance) {
  const std::array<double, 3> a{0, 0, 0};
  const std::array<double, 3> b{2, 0, 0};
  const std::array<double, 3> c{0, 2, 0};
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({0.5, 0.5, 3}, a, b, c), 9.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({-1, 0, 0}, a, b, c), 1.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({2, 2, 0}, a, b, c), 2.0);
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({3, 0, 1}, a, b, c), 2.0);
  // Degenerate (collinear) triangle: distance to the segment.
  EXPECT_DOUBLE_EQ(detail::point_triangle_distance_squared({1, 1, 0}, a, b, {1, 0, 0}), 1.0);
}

}  // namespace
}  // namespace typemerge::core
