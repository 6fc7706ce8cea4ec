// Tests of extract_type_merged (the fused merge of flat disks in lattice blocks), up the
// oracle ladder: every cube configuration alone and in random neighbourhoods; planes of every
// orientation, where the merged surface must keep the plane, its border and its area; closed
// smooth surfaces (spheres, torus) for topology, distance and reduction; noise and blobs for
// watertightness under many ambiguities; thin sheets on thick slices for crossings in
// millimetres; pieces, threads, open borders and options. Every surface is compared with
// marching cubes': same boundary, Euler characteristic and components, no crossing pair
// (exact predicates), and within epsilon over both surfaces (sampled, not only at vertices).
#include "core/type_merging.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/cube_tables.h"
#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

using test::noise_volume;
using test::sample_volume;
using test::set_cube;
using test::sphere_volume;

// Under the sanitizers (CI's second build) the same checks on fewer and coarser cases: the
// point is memory and undefined behaviour there, and every check runs 20–70× slower.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

const ExtractOptions kOpen{.close_borders = false};
const ExtractOptions kClosed{.close_borders = true};

struct Extracted {
  TriangleMesh mc;
  TriangleMesh tm;
  MergeStats stats;
};

Extracted extract_both(const Volume& volume, float iso, const ExtractOptions& extract,
                       const MergeOptions& options = {}) {
  Extracted out;
  out.mc = extract_isosurface(volume, iso, extract);
  out.tm = extract_type_merged(volume, iso, extract, options, &out.stats);
  return out;
}

double ratio(const Extracted& e) {
  return static_cast<double>(e.tm.triangles.size()) / static_cast<double>(e.mc.triangles.size());
}

// Hausdorff distance between the two surfaces, sampled every 0.2 voxel over both (0.5
// under the sanitizers).
double sampled_hausdorff(const Extracted& e) {
  return surface_distance(e.mc, e.tm, kSanitized ? 0.5 : 0.2, 1).hausdorff();
}

// What the merge keeps, for closed or open marching-cubes meshes.
void expect_same_topology(const Extracted& e) {
  const MeshCheck mc = check_mesh(e.mc);
  const MeshCheck tm = check_mesh(e.tm);
  EXPECT_EQ(tm.non_manifold_edges, mc.non_manifold_edges);
  EXPECT_EQ(tm.non_manifold_vertices, mc.non_manifold_vertices);
  EXPECT_EQ(tm.inconsistent_edges, 0u);
  EXPECT_EQ(tm.degenerate_triangles, 0u);
  EXPECT_EQ(tm.boundary_edges, mc.boundary_edges);
  EXPECT_EQ(tm.euler_characteristic, mc.euler_characteristic);
  EXPECT_EQ(tm.components, mc.components);
  EXPECT_EQ(tm.vertices, e.tm.positions.size());  // compacted: no unused vertex
  EXPECT_LE(e.tm.triangles.size(), e.mc.triangles.size());
  EXPECT_EQ(e.stats.triangles_before, e.mc.triangles.size());
  EXPECT_EQ(e.stats.triangles_after, e.tm.triangles.size());
  EXPECT_EQ(e.stats.vertices_before, e.mc.positions.size());
  EXPECT_EQ(e.stats.vertices_after, e.tm.positions.size());
  // Every output vertex is a marching-cubes vertex, unmoved, with its normal (type merging
  // computes the normals of the vertices it keeps only, after the merge).
  ASSERT_EQ(e.mc.normals.size(), e.mc.positions.size());
  ASSERT_EQ(e.tm.normals.size(), e.tm.positions.size());
  std::vector<std::pair<std::array<float, 3>, std::array<float, 3>>> mc_vertices;
  for (std::size_t v = 0; v < e.mc.positions.size(); ++v) {
    mc_vertices.emplace_back(e.mc.positions[v], e.mc.normals[v]);
  }
  std::sort(mc_vertices.begin(), mc_vertices.end());
  for (std::size_t v = 0; v < e.tm.positions.size(); ++v) {
    const auto found = std::lower_bound(
        mc_vertices.begin(), mc_vertices.end(), e.tm.positions[v],
        [](const auto& vertex, const std::array<float, 3>& p) { return vertex.first < p; });
    ASSERT_TRUE(found != mc_vertices.end() && found->first == e.tm.positions[v]);
    ASSERT_EQ(found->second, e.tm.normals[v]);
  }
  // No two triangles cross (exact predicates), as in marching cubes (whose own tests check
  // it).
  EXPECT_TRUE(find_self_intersections(e.tm).pairs.empty());
}

void expect_within_epsilon(const Extracted& e, double epsilon) {
  if (e.mc.empty()) return;
  // The bound is exact (slab argument); sampling adds nothing to it, float rounding little.
  EXPECT_LE(sampled_hausdorff(e), epsilon + 1e-4);
  EXPECT_LE(max_vertex_distance(e.mc, e.tm, 1), epsilon + 1e-4);
}

// ---- Every configuration --------------------------------------------------------------------

// Each of the 256 cube indices alone (closed off: a block of the closed borders' padding
// around it) and in random 4×4×4 neighbourhoods, where blocks of two and four cubes see it
// beside everything else.
TEST(TypeMerging, AllConfigurationsAloneAndInRandomNeighbourhoods) {
  std::mt19937 rng(3);
  std::size_t merged = 0;
  for (unsigned c = 0; c < 256; ++c) {
    for (int trial = 0; trial < (kSanitized ? 1 : 2); ++trial) {
      SCOPED_TRACE(testing::Message() << "index " << c << " trial " << trial);
      Volume alone({2, 2, 2}, {});
      set_cube(alone, c, 0, 0, 0, rng);
      const Extracted a = extract_both(alone, 0.0f, kClosed);
      expect_same_topology(a);
      EXPECT_TRUE(check_mesh(a.tm).closed_manifold());
      expect_within_epsilon(a, 0.5);

      Volume around = noise_volume(4, 4, 4, static_cast<unsigned>(rng()));
      for (float& v : around.samples()) v -= 0.5f;
      set_cube(around, c, 1, 1, 1, rng);
      for (const ExtractOptions& extract : {kClosed, kOpen}) {
        if (kSanitized && !extract.close_borders) continue;
        const Extracted e = extract_both(around, 0.0f, extract);
        expect_same_topology(e);
        expect_within_epsilon(e, 0.5);
        merged += e.mc.triangles.size() - e.tm.triangles.size();
      }
      if (testing::Test::HasFailure()) return;
    }
  }
  EXPECT_GT(merged, 0u);
}

// ---- Planes ---------------------------------------------------------------------------------

struct PlaneCase {
  const char* name;
  std::array<double, 3> normal;  // inside: normal·p < offset
  double offset;
  double max_ratio;  // TM / MC triangles must not exceed this
};

constexpr PlaneCase kPlanes[] = {
    {"z", {0, 0, 1}, 7.37, 0.08},
    {"x", {1, 0, 0}, 7.61, 0.08},
    {"(0,1,1)", {0, 1, 1}, 14.3, 0.1},
    {"(1,-1,0)", {1, -1, 0}, 0.41, 0.1},
    {"(1,1,2)", {1, 1, 2}, 20.3, 0.2},
    {"(2,1,-1)", {2, 1, -1}, 8.3, 0.2},
    {"(1,1,1)", {1, 1, 1}, 22.6, 0.2},
    {"(3,1,1)", {3, 1, 1}, 30.2, 0.2},
    {"(1,2,3)", {1, 2, 3}, 40.3, 0.2},
    // 8.6 % before triangulations with more caps or needles than marching cubes' were
    // refused: on the open border x = 0 its boxes' loops keep long straight runs of vertices
    // that only fans can join (20.2 % since).
    {"(0.31,0.52,0.79)", {0.31, 0.52, 0.79}, 12.1, 0.25},
};

TEST(TypeMerging, PlanesStayExactlyPlanarWithTheirBorderAndArea) {
  for (const PlaneCase& plane : kPlanes) {
    SCOPED_TRACE(plane.name);
    const auto& n = plane.normal;
    const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const Volume volume = sample_volume(33, 32, 31, [&](double x, double y, double z) {
      return (plane.offset - (n[0] * x + n[1] * y + n[2] * z)) / length;
    });
    const Extracted e = extract_both(volume, 0.0f, kOpen);
    ASSERT_FALSE(e.mc.empty());
    expect_same_topology(e);
    // On a plane the merged surface covers the same region with the same border: same area,
    // every triangle facing +n.
    for (const auto& t : e.tm.triangles) {
      const auto a = triangle_area_vector(e.tm, t);
      ASSERT_GT(a[0] * n[0] + a[1] * n[1] + a[2] * n[2], 0.0);
    }
    EXPECT_NEAR(check_mesh(e.tm).area / check_mesh(e.mc).area, 1.0, 1e-5);
    std::printf("[ plane    ] %-18s MC %6zu -> TM %5zu triangles (%.1f %%)\n", plane.name,
                e.mc.triangles.size(), e.tm.triangles.size(), 100.0 * ratio(e));
    EXPECT_LE(ratio(e), plane.max_ratio);
  }
}

// ---- Closed smooth surfaces -----------------------------------------------------------------

void check_smooth_closed(const char* name, const Volume& volume, std::int64_t chi,
                         double max_ratio, const MergeOptions& options = {}) {
  SCOPED_TRACE(name);
  const Extracted e = extract_both(volume, 0.0f, kClosed, options);
  const MeshCheck tm = check_mesh(e.tm);
  EXPECT_TRUE(tm.closed_manifold());
  EXPECT_EQ(tm.euler_characteristic, chi);
  EXPECT_EQ(tm.components, 1u);
  expect_same_topology(e);
  expect_within_epsilon(e, options.epsilon_voxels);
  // Chords cut corners of convex parts, by at most epsilon.
  EXPECT_NEAR(tm.volume / check_mesh(e.mc).volume, 1.0, 0.04);
  std::printf("[ closed   ] %-16s MC %6zu -> TM %6zu triangles (%.1f %%), Hausdorff %.3f voxel\n",
              name, e.mc.triangles.size(), e.tm.triangles.size(), 100.0 * ratio(e),
              sampled_hausdorff(e));
  EXPECT_LE(ratio(e), max_ratio);
}

TEST(TypeMerging, SpheresKeepTopologyAndStayWithinEpsilon) {
  check_smooth_closed("sphere R=10.3", sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 2, 0.45);
  if (!kSanitized) {
    check_smooth_closed("sphere R=20.3", sphere_volume(46, 20.3, 22.4, 22.7, 22.2), 2, 0.3);
  }
}

TEST(TypeMerging, TorusKeepsTopology) {
  const Volume volume = sample_volume(32, 32, 14, [&](double x, double y, double z) {
    const double dx = x - 15.6;
    const double dy = y - 15.3;
    const double dz = z - 6.7;
    const double ring = std::sqrt(dx * dx + dy * dy) - 10.0;
    return 4.0 - std::sqrt(ring * ring + dz * dz);
  });
  check_smooth_closed("torus 10/4", volume, 0, 0.6);
}

TEST(TypeMerging, SmallerEpsilonIsRespectedAndZeroMergesOnlyFlatDisks) {
  MergeOptions options;
  options.epsilon_voxels = 0.2;
  check_smooth_closed("sphere eps 0.2", sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 2, 0.8,
                      options);
  options.epsilon_voxels = 0.0;
  const Extracted e = extract_both(sphere_volume(26, 10.3, 12.4, 12.7, 12.2), 0.0f, kClosed,
                                   options);
  expect_same_topology(e);
  expect_within_epsilon(e, 0.0);
}

// Triangle normals of the merged sphere point away from the centre.
TEST(TypeMerging, SphereHasNoFoldedTriangles) {
  const double c[3] = {22.4, 22.7, 22.2};
  const Extracted e = extract_both(sphere_volume(46, 20.3, c[0], c[1], c[2]), 0.0f, kClosed);
  for (const auto& t : e.tm.triangles) {
    const auto tn = triangle_area_vector(e.tm, t);
    double radial = 0.0;
    for (int a = 0; a < 3; ++a) {
      double centroid = 0.0;
      for (auto v : t) centroid += e.tm.positions[v][a] / 3.0;
      radial += tn[a] * (centroid - c[a]);
    }
    ASSERT_GT(radial, 0.0);
  }
}

// ---- Noise and blobs --------------------------------------------------------------------------

TEST(TypeMerging, NoiseStaysWatertightAndManifold) {
  for (unsigned seed = 1; seed <= (kSanitized ? 3u : 12u); ++seed) {
    SCOPED_TRACE(seed);
    const Volume volume = noise_volume(11, 10, 9, seed);
    for (const ExtractOptions& extract : {kClosed, kOpen}) {
      const Extracted e = extract_both(volume, 0.5f, extract);
      expect_same_topology(e);
      expect_within_epsilon(e, 0.5);
      if (extract.close_borders) {
        EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
      }
    }
  }
}

// Classic MC leaves holes on ambiguous faces, which a block's loop (its edges on the block's
// faces) cannot see: type merging refuses it.
TEST(TypeMerging, ClassicModeIsRefused) {
  const ExtractOptions kClassic{.close_borders = true, .mode = ExtractOptions::Mode::classic};
  EXPECT_THROW(extract_type_merged(noise_volume(11, 10, 9, 1), 0.5f, kClassic),
               std::invalid_argument);
}

Volume blob_volume(unsigned seed, double iso_shift) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 24.0);
  std::array<std::array<double, 3>, 6> centres{};
  for (auto& c : centres) c = {u(rng), u(rng), u(rng)};
  return sample_volume(24, 24, 24, [&](double x, double y, double z) {
    double f = 0.0;
    for (const auto& c : centres) {
      const double d2 = (x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) + (z - c[2]) * (z - c[2]);
      f += std::exp(-d2 / 18.0);
    }
    return f - iso_shift;
  });
}

TEST(TypeMerging, BlobsStayWatertightAndManifold) {
  for (unsigned seed = 1; seed <= (kSanitized ? 3u : 10u); ++seed) {
    SCOPED_TRACE(seed);
    const Extracted e = extract_both(blob_volume(seed, 0.4), 0.0f, kClosed);
    expect_same_topology(e);
    EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
    expect_within_epsilon(e, 0.5);
    EXPECT_LT(ratio(e), 0.6);
  }
}

// Caps (an angle above 170°) and needles (below 1°) in millimetres, counted on the mesh as
// it is written (patient coordinates).
ExtremeAngles extremes_in_mm(TriangleMesh mesh, const IndexToPatient& geometry) {
  to_patient(mesh, geometry);
  return count_extreme_angles(mesh);
}

double share(std::size_t part, std::size_t all) {
  return 100.0 * static_cast<double>(part) / static_cast<double>(all);
}

// Caps and needles of both surfaces over several volumes.
struct ShapeTally {
  ExtremeAngles mc, tm;
  std::size_t triangles_mc = 0, triangles_tm = 0;

  // Extracts both surfaces of `volume` (its geometry set), with the same topology, and counts.
  void add(const Volume& volume) {
    const Extracted e = extract_both(volume, 0.0f, kClosed);
    expect_same_topology(e);
    mc += extremes_in_mm(e.mc, volume.geometry());
    tm += extremes_in_mm(e.tm, volume.geometry());
    triangles_mc += e.mc.triangles.size();
    triangles_tm += e.tm.triangles.size();
  }
  void print(const char* what) const {
    std::printf(
        "[ shapes   ] %s: MC %zu triangles, needles %.2f %%, caps %.2f %%; TM %zu, %.2f %%, "
        "%.2f %%\n",
        what, triangles_mc, share(mc.below_1, triangles_mc), share(mc.above_170, triangles_mc),
        triangles_tm, share(tm.below_1, triangles_tm), share(tm.above_170, triangles_tm));
  }
  void expect_shares_no_higher() const {
    EXPECT_LE(share(tm.below_1, triangles_tm), share(mc.below_1, triangles_mc));
    EXPECT_LE(share(tm.above_170, triangles_tm), share(mc.above_170, triangles_mc));
  }
};

// Without vertex normals only the normals go: the merged surface is the one made with them,
// on one piece or several, on one thread or two.
TEST(TypeMerging, WithoutVertexNormalsOnlyTheNormalsGo) {
  const std::array<Volume, 3> volumes = {noise_volume(11, 10, 9, 1), noise_volume(11, 10, 9, 2),
                                         blob_volume(1, 0.4)};
  const std::array<float, 3> isos = {0.5f, 0.5f, 0.0f};
  for (std::size_t i = 0; i < volumes.size(); ++i) {
    for (ExtractOptions extract : {kClosed, kOpen}) {
      for (unsigned threads : {1u, 2u}) {
        SCOPED_TRACE(testing::Message() << i << " " << extract.close_borders << " " << threads);
        MergeOptions options;
        options.slab_layers = 4;
        options.threads = threads;
        const TriangleMesh with = extract_type_merged(volumes[i], isos[i], extract, options);
        extract.vertex_normals = false;
        const TriangleMesh without = extract_type_merged(volumes[i], isos[i], extract, options);
        extract.vertex_normals = true;
        ASSERT_FALSE(with.empty());
        ASSERT_EQ(with.normals.size(), with.positions.size());
        EXPECT_TRUE(without.normals.empty());
        EXPECT_EQ(without.positions, with.positions);
        EXPECT_EQ(without.triangles, with.triangles);
      }
    }
  }
}

// Merged disks are re-triangulated for shape (and refused where that makes more caps or
// needles than their marching-cubes triangles), and so are single cubes whose rows fail
// (their polygon fanned by the case table otherwise): on noisy blobs, on even and on thick
// slices, type merging makes fewer needles than marching cubes, no more caps, and its
// shares of both are no higher.
TEST(TypeMerging, NoMoreNeedlesOrCapsThanMarchingCubes) {
  for (const double slice : {1.0, 3.0}) {
    IndexToPatient geometry;
    geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0, slice}}};
    ShapeTally tally;
    for (unsigned seed = 1; seed <= (kSanitized ? 2u : 6u); ++seed) {
      Volume volume = blob_volume(seed, 0.4);
      std::mt19937 rng(seed);
      std::uniform_real_distribution<float> noise(-0.04f, 0.04f);
      for (float& v : volume.samples()) v += noise(rng);
      volume.set_geometry(geometry);
      tally.add(volume);
    }
    SCOPED_TRACE(slice);
    tally.print(slice == 1.0 ? "blobs, 1 mm slices" : "blobs, 3 mm slices");
    EXPECT_GT(tally.mc.below_1, 0u);  // the noise makes some, or the test shows nothing
    EXPECT_LT(tally.tm.below_1, tally.mc.below_1);
    EXPECT_LE(tally.tm.above_170, tally.mc.above_170);
    tally.expect_shares_no_higher();
  }
}

// Noisy tubes along z on CT's thick slices (1.07 × 1.07 × 3 mm), as bone cortex runs: where
// the wall passes within a hair of a box's face, the box's loop vertices on that face are
// spread over its disk and no new edge may join two of them, so the loop can only be fanned
// from its few other vertices, into caps and needles. Such triangulations are refused (without
// that, type merging's caps were 0.50 % of its triangles here against marching cubes'
// 0.20 %), so its shares of caps and needles are no higher than marching cubes', while it
// still merges most of the walls.
TEST(TypeMerging, TubesOnThickSlicesKeepTheirShape) {
  IndexToPatient geometry;
  geometry.axes = {{{1.07, 0, 0}, {0, 1.07, 0}, {0, 0, 3.0}}};
  ShapeTally tally;
  for (unsigned seed = 1; seed <= (kSanitized ? 4u : 8u); ++seed) {
    SCOPED_TRACE(seed);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> noise(-0.03, 0.03);
    const double radius = 6.0 + 1.3 * seed;
    Volume volume = sample_volume(36, 36, 16, [&](double x, double y, double) {
      return std::hypot(x - 17.3, y - 17.6) - radius + noise(rng);
    });
    volume.set_geometry(geometry);
    tally.add(volume);
  }
  tally.print("tubes");
  EXPECT_GT(tally.mc.above_170, 0u);  // marching cubes makes some, or the test shows nothing
  tally.expect_shares_no_higher();
  EXPECT_LT(static_cast<double>(tally.triangles_tm),
            0.25 * static_cast<double>(tally.triangles_mc));
}

// Thin noisy spherical shells (two sheets about a voxel apart, as cortex is) on a grid of
// thick slices (0.7 × 0.7 × 3 mm): blocks hold both sheets, which each merge only when a
// plane parts them. No pair crosses in patient millimetres as written, with marching cubes'
// topology.
TEST(TypeMerging, ThinShellsOnThickSlicesDoNotCross) {
  IndexToPatient geometry;
  geometry.axes = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 3.0}}};
  std::size_t separated = 0;
  for (double thickness : {0.8, 1.1, 1.6}) {
    for (unsigned seed = 1; seed <= 4; ++seed) {
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
      const Extracted e = extract_both(volume, 0.0f, kClosed);
      expect_same_topology(e);
      EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
      TriangleMesh written = e.tm;
      to_patient(written, geometry);
      EXPECT_TRUE(find_self_intersections(written).pairs.empty());
      separated += e.stats.rejected_separation;
      EXPECT_LT(ratio(e), 0.95);
    }
  }
  EXPECT_GT(separated, 0u) << "blocks holding two sheets should have been seen";
}

// A sphere of 20 mm sampled on 1 × 1 × 3 mm voxels (as CT with thick slices), merged in
// blocks shaped by the spacing (8 × 8 × 4 cubes, grown 2 × 2 × 2 → 4 × 4 × 2 → 8 × 8 × 4) and
// in cubic blocks: both keep every guarantee, in millimetres as written too; the shaped
// blocks merge more. On an isotropic grid the option changes nothing.
TEST(TypeMerging, BlocksFollowThickSlices) {
  IndexToPatient geometry;
  geometry.axes = {{{1.0, 0, 0}, {0, 1.0, 0}, {0, 0, 3.0}}};
  Volume volume = sample_volume(48, 48, 18, [&](double x, double y, double z) {
    const double dx = x - 23.6;
    const double dy = y - 23.3;
    const double dz = 3.0 * (z - 8.4);
    return 20.3 - std::sqrt(dx * dx + dy * dy + dz * dz);
  });
  const Extracted cubic_iso = extract_both(volume, 0.0f, kClosed, {.blocks_follow_spacing = false});
  const Extracted shaped_iso = extract_both(volume, 0.0f, kClosed);
  EXPECT_EQ(shaped_iso.tm.triangles, cubic_iso.tm.triangles);
  EXPECT_EQ(shaped_iso.tm.positions, cubic_iso.tm.positions);

  volume.set_geometry(geometry);
  std::size_t triangles[2] = {};
  for (bool follow : {false, true}) {
    SCOPED_TRACE(follow);
    const Extracted e =
        extract_both(volume, 0.0f, kClosed, {.blocks_follow_spacing = follow});
    expect_same_topology(e);
    EXPECT_TRUE(check_mesh(e.tm).closed_manifold());
    expect_within_epsilon(e, 0.5);
    TriangleMesh written = e.tm;
    to_patient(written, geometry);
    EXPECT_TRUE(find_self_intersections(written).pairs.empty());
    triangles[follow ? 1 : 0] = e.tm.triangles.size();
    std::printf("[ thick    ] blocks %s: MC %zu -> TM %zu triangles (%.1f %%)\n",
                follow ? "shaped" : "cubic ", e.mc.triangles.size(), e.tm.triangles.size(),
                100.0 * ratio(e));
  }
  EXPECT_LT(triangles[1], triangles[0]);
}

// ---- Pieces, threads, borders, options --------------------------------------------------------

std::vector<Volume> piece_test_volumes() {
  std::vector<Volume> volumes;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    Volume v = noise_volume(11, 10, 13, seed);
    for (float& s : v.samples()) s -= 0.5f;
    volumes.push_back(std::move(v));
  }
  volumes.push_back(sphere_volume(26, 10.3, 12.4, 12.7, 12.2));
  for (unsigned seed = 1; seed <= 2; ++seed) volumes.push_back(blob_volume(seed, 0.4));
  return volumes;
}

// Pieces of slab_layers cube layers (blocks are cut at their seams), merged alone and
// stitched: the same guarantees as one piece, the MC counts in the statistics, and one output
// for any thread count. Pieces of one layer are the extreme case: every vertex is on a seam.
TEST(TypeMerging, PiecesStitchIntoTheSameSurfaceForAnyThreadCount) {
  const std::vector<Volume> volumes = piece_test_volumes();
  for (std::size_t i = 0; i < volumes.size(); i += kSanitized ? 2 : 1) {
    SCOPED_TRACE(i);
    AmbiguityStats mc_ambiguity;
    ExtractOptions extract = kClosed;
    extract.stats = &mc_ambiguity;
    const TriangleMesh mc = extract_isosurface(volumes[i], 0.0f, extract);
    for (unsigned slab_layers : {1u, 3u, 32u}) {
      SCOPED_TRACE(slab_layers);
      MergeOptions options;
      options.slab_layers = slab_layers;
      Extracted one{mc, {}, {}};
      AmbiguityStats ambiguity;
      extract.stats = &ambiguity;
      one.tm = extract_type_merged(volumes[i], 0.0f, extract, options, &one.stats);
      EXPECT_EQ(ambiguity.boundary_cubes, mc_ambiguity.boundary_cubes);
      EXPECT_EQ(ambiguity.cubes_with_ambiguous_faces, mc_ambiguity.cubes_with_ambiguous_faces);
      expect_same_topology(one);
      EXPECT_TRUE(check_mesh(one.tm).closed_manifold());
      expect_within_epsilon(one, options.epsilon_voxels);
      if (slab_layers >= 3 || slab_layers == 0) {
        EXPECT_LT(one.tm.triangles.size(), mc.triangles.size());
      }
      for (unsigned threads : {2u, 3u}) {
        SCOPED_TRACE(threads);
        options.threads = threads;
        const TriangleMesh many = extract_type_merged(volumes[i], 0.0f, kClosed, options);
        EXPECT_EQ(many.triangles, one.tm.triangles);
        EXPECT_EQ(many.positions, one.tm.positions);
        EXPECT_EQ(many.normals, one.tm.normals);
      }
    }
  }
}

// slices_done: disjoint ranges that cover every slice once, each never read again: releasing
// them as reported (they then read as zeros), with the idle slice buffers' pages returned too,
// leaves every output the same, for one and several threads, closed and open borders, with
// and without normals, float and int16 samples.
TEST(TypeMerging, SlicesReportedDoneAreNotReadAgain) {
  // Big enough that released slices span whole pages (64 × 64 samples a slice).
  Volume volume = sample_volume(64, 64, 40, [](double x, double y, double z) {
    return 14.0 - std::sqrt((x - 31.5) * (x - 31.5) + (y - 30.2) * (y - 30.2) +
                            (z - 19.7) * (z - 19.7) * 1.7) +
           2.5 * std::sin(x * 0.4) * std::cos(y * 0.3 + z * 0.2);
  });
  for (const bool int16 : {false, true}) {
    SCOPED_TRACE(int16);
    Volume source = volume;
    if (int16) {
      for (float& v : source.samples()) v = std::round(v * 100.0f) + 0.0f;  // no −0
      ASSERT_TRUE(source.to_int16_if_exact());
    }
    const float iso = int16 ? 50.0f : 0.5f;
    for (const bool closed : {true, false}) {
      for (const bool normals : {false, true}) {
        for (unsigned threads : {1u, 2u}) {
          SCOPED_TRACE(testing::Message() << closed << normals << threads);
          ExtractOptions extract;
          extract.close_borders = closed;
          extract.vertex_normals = normals;
          MergeOptions options;
          options.slab_layers = 8;
          options.threads = threads;
          const TriangleMesh kept = extract_type_merged(source, iso, extract, options);
          Volume released = source;
          std::mutex reports_mutex;
          std::vector<std::pair<std::int64_t, std::int64_t>> reports;
          options.slices_done = [&](std::int64_t begin, std::int64_t end) {
            released.release_slices(begin, end);
            const std::lock_guard lock(reports_mutex);
            reports.emplace_back(begin, end);
          };
          options.return_idle_pages = true;
          const TriangleMesh mesh = extract_type_merged(released, iso, extract, options);
          EXPECT_EQ(mesh.triangles, kept.triangles);
          EXPECT_EQ(mesh.positions, kept.positions);
          EXPECT_EQ(mesh.normals, kept.normals);
          // About 40 / 8 pieces: each one's own slices and those it shares with the one below.
          ASSERT_GE(reports.size(), 8u);
          std::sort(reports.begin(), reports.end());
          std::int64_t covered = 0;
          for (const auto& [begin, end] : reports) {
            EXPECT_EQ(begin, covered);
            EXPECT_LT(begin, end);
            covered = end;
          }
          EXPECT_EQ(covered, released.size().nz);
          // The release did happen: the second slice (on whole pages) reads as zeros now.
#if defined(__linux__)
          EXPECT_EQ(std::as_const(released).at(20, 20, 1), 0.0f);
          EXPECT_NE(std::as_const(source).at(20, 20, 1), 0.0f);
#endif
        }
      }
    }
  }
}

// The same volume on 3 mm slices over 1 mm pixels (blocks of 8 × 8 × 4 cubes).
Volume on_3mm_slices(Volume volume) {
  IndexToPatient geometry = volume.geometry();
  geometry.axes[2] = {0.0, 0.0, 3.0};
  volume.set_geometry(geometry);
  return volume;
}

// Pieces are cut where the estimated surface is equal: a volume whose surface is all in its
// top quarter gets short pieces there and one tall piece below; cuts fall on multiples of the
// blocks' z edge when pieces are tall; every layer is in exactly one piece; threads do not
// matter.
TEST(TypeMerging, PieceBoundsBalanceTheSurface) {
  // 20 × 20 × 160 samples: a stack of thin plates (many surfaces) in slices 120..159 only.
  const Volume volume = test::sample_volume(20, 20, 160, [](double x, double, double z) {
    if (z < 120) return -1.0;
    return std::fmod(z + 0.25 * x, 4.0) < 2.0 ? 1.0 : -1.0;
  });
  const std::int64_t layers = detail::cube_layer_count(volume, 0.0f, kClosed);
  ASSERT_EQ(layers, 161);
  MergeOptions options;
  options.slab_layers = 40;
  const std::vector<std::int64_t> bounds =
      detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 1);
  ASSERT_GE(bounds.size(), 3u);
  EXPECT_EQ(bounds.front(), 0);
  EXPECT_EQ(bounds.back(), layers);
  EXPECT_EQ(bounds.size() - 1, 4u);  // round(161 / 40)
  for (std::size_t k = 1; k + 1 < bounds.size(); ++k) {
    EXPECT_LT(bounds[k - 1], bounds[k]);
    EXPECT_EQ(bounds[k] % options.block_cubes, 0) << bounds[k];
  }
  // Equal heights would cut at 40, 80, 120; the empty bottom is one piece here.
  EXPECT_GE(bounds[1], 112);
  EXPECT_EQ(detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 3), bounds);
  // On 3 mm slices over 1 mm pixels blocks are 8 × 8 × 4 cubes: cuts fall on multiples of 4.
  {
    const std::vector<std::int64_t> cuts =
        detail::piece_bounds(on_3mm_slices(volume), 0.0f, kClosed, options, layers, 1);
    ASSERT_EQ(cuts.size(), bounds.size());
    for (std::size_t k = 1; k + 1 < cuts.size(); ++k) EXPECT_EQ(cuts[k] % 4, 0) << cuts[k];
  }
  // Pieces of one layer each, and one piece.
  options.slab_layers = 1;
  const std::vector<std::int64_t> single = detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 2);
  ASSERT_EQ(single.size(), static_cast<std::size_t>(layers) + 1);
  for (std::int64_t k = 0; k <= layers; ++k) EXPECT_EQ(single[static_cast<std::size_t>(k)], k);
  options.slab_layers = 0;
  EXPECT_EQ(detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 1),
            (std::vector<std::int64_t>{0, layers}));
  EXPECT_TRUE(detail::piece_bounds(volume, 0.0f, kClosed, options, 0, 1).empty());
}

// The estimate that cuts the pieces, scaled to all rows, is about each piece's marching-cubes
// vertex count (it sizes the piece's outputs); the pieces are the same with or without it.
TEST(TypeMerging, PieceBoundsEstimateEachPiecesVertices) {
  const Volume volume = test::sample_volume(48, 48, 96, [](double x, double y, double z) {
    const double r = std::hypot(x - 24.0, y - 24.0);
    return std::fmod(z + 0.3 * x, 6.0) < 3.0 && r < 20.0 - 0.1 * z ? 1.0 : -1.0;
  });
  const std::int64_t layers = detail::cube_layer_count(volume, 0.0f, kClosed);
  MergeOptions options;
  options.slab_layers = 24;
  std::vector<double> vertices;
  const std::vector<std::int64_t> bounds =
      detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 1, &vertices);
  EXPECT_EQ(detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 1), bounds);
  ASSERT_GE(bounds.size(), 3u);
  ASSERT_EQ(vertices.size(), bounds.size() - 1);
  for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
    const detail::SurfacePiece piece =
        detail::extract_layers(volume, 0.0f, kClosed, bounds[k], bounds[k + 1]);
    const auto made = static_cast<double>(piece.mesh.positions.size());
    EXPECT_NEAR(vertices[k], made, 0.25 * made) << "piece " << k;
    // A piece extracted with the estimate is the one extracted without it.
    const detail::SurfacePiece sized = detail::extract_layers(
        volume, 0.0f, kClosed, bounds[k], bounds[k + 1], false, vertices[k]);
    EXPECT_EQ(sized.mesh.positions, piece.mesh.positions);
    EXPECT_EQ(sized.mesh.triangles, piece.mesh.triangles);
  }
  options.slab_layers = 0;
  detail::piece_bounds(volume, 0.0f, kClosed, options, layers, 1, &vertices);
  EXPECT_TRUE(vertices.empty());
}

// A square column through every slice of a 40 × 40 × nz volume, closed by a cap at each end.
Volume column_through_every_slice(std::int64_t nz) {
  return test::sample_volume(40, 40, nz, [](double x, double y, double) {
    return x >= 2 && x <= 37 && y >= 2 && y <= 37 ? 1.0 : -1.0;
  });
}

// The pieces' bounds of `volume` at iso 0, closed borders, slab_layers 32.
std::vector<std::int64_t> bounds_of_32_layer_pieces(const Volume& volume, unsigned threads) {
  MergeOptions options;
  options.slab_layers = 32;
  return detail::piece_bounds(volume, 0.0f, kClosed, options,
                              detail::cube_layer_count(volume, 0.0f, kClosed), threads);
}

// A body cut by both ends of the volume (a column through every slice) is closed by two caps,
// each a layer of flat surface as large as its cross-section: the estimate sees them, so the
// first and last pieces are shorter than the others (counting x-edges alone, every layer
// looked the same and the pieces had equal heights).
TEST(TypeMerging, PieceBoundsCountTheCapsOfACutBody) {
  const std::vector<std::int64_t> bounds =
      bounds_of_32_layer_pieces(column_through_every_slice(192), 2);
  ASSERT_EQ(bounds.size() - 1, 6u);
  const std::int64_t first = bounds[1] - bounds[0];
  const std::int64_t last = bounds[6] - bounds[5];
  EXPECT_LT(first, 32);
  EXPECT_LT(last, 32);
  for (std::size_t k = 1; k + 2 < bounds.size(); ++k) {
    EXPECT_GT(bounds[k + 1] - bounds[k], first) << k;
    EXPECT_GT(bounds[k + 1] - bounds[k], last) << k;
  }
}

// An odd count of pieces is rounded up to even, so two threads share them evenly (nine pieces
// left one thread working alone on the last): 289 layers make 10 pieces of 32 layers, not 9;
// a volume of under 1.5 pieces stays one piece, and pieces of one layer stay one a layer.
TEST(TypeMerging, PieceCountIsEvenSoTwoThreadsShareThem) {
  const std::vector<std::int64_t> nine = bounds_of_32_layer_pieces(column_through_every_slice(288), 2);
  EXPECT_EQ(nine.size() - 1, 10u);
  const std::vector<std::int64_t> four = bounds_of_32_layer_pieces(column_through_every_slice(128), 1);
  EXPECT_EQ(four.size() - 1, 4u);
  const std::vector<std::int64_t> one = bounds_of_32_layer_pieces(column_through_every_slice(40), 1);
  EXPECT_EQ(one, (std::vector<std::int64_t>{0, 41}));
  MergeOptions options;
  options.slab_layers = 1;
  const Volume odd = column_through_every_slice(20);
  const std::int64_t layers = detail::cube_layer_count(odd, 0.0f, kClosed);
  ASSERT_EQ(layers % 2, 1);
  EXPECT_EQ(detail::piece_bounds(odd, 0.0f, kClosed, options, layers, 1).size() - 1,
            static_cast<std::size_t>(layers));
}

// On 3 mm slices (blocks 8 × 8 × 4 cubes) cuts fall on multiples of 4, the blocks' z edge,
// not of 8 (block_cubes), so pieces can be nearer equal: a column through every slice, whose
// layers cost the same but for the caps, cut into four pieces of about 28 layers. The same
// volume on isotropic voxels (blocks of 8 along z) is cut on multiples of 8.
TEST(TypeMerging, PieceBoundsSnapToTheBlocksZEdge) {
  const Volume volume = column_through_every_slice(112);
  const std::vector<std::int64_t> cubes = bounds_of_32_layer_pieces(volume, 1);
  ASSERT_EQ(cubes.size(), 5u);
  for (std::size_t k = 1; k + 1 < cubes.size(); ++k) EXPECT_EQ(cubes[k] % 8, 0) << cubes[k];
  const std::vector<std::int64_t> thick = bounds_of_32_layer_pieces(on_3mm_slices(volume), 1);
  ASSERT_EQ(thick.size(), 5u);
  bool off_eight = false;
  for (std::size_t k = 1; k + 1 < thick.size(); ++k) {
    EXPECT_EQ(thick[k] % 4, 0) << thick[k];
    off_eight = off_eight || thick[k] % 8 != 0;
  }
  EXPECT_TRUE(off_eight);
}

// Open borders across seams: boundaries stay exactly as marching cubes leaves them (the same
// boundary edges; their vertices lie on block faces, so they stay).
TEST(TypeMerging, PiecesKeepOpenBorders) {
  MergeOptions options;
  options.slab_layers = 3;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    SCOPED_TRACE(seed);
    const Extracted e = extract_both(noise_volume(11, 10, 13, seed), 0.5f, kOpen, options);
    EXPECT_GT(check_mesh(e.mc).boundary_edges, 0u);
    expect_same_topology(e);
  }
}

// Every block size keeps the guarantees, and the blocks of the largest size do get merged
// (boxes of that size pass on a smooth sphere). Larger blocks usually, not always, give fewer
// triangles: a block that replaces its halves is not compared with them (measured: the R = 10.3
// sphere 988 triangles with blocks of 4, 996 with blocks of 8).
TEST(TypeMerging, BlockSizesKeepTheGuarantees) {
  const Volume volume = kSanitized ? sphere_volume(26, 10.3, 12.4, 12.7, 12.2)
                                   : sphere_volume(46, 20.3, 22.4, 22.7, 22.2);
  for (unsigned block : {2u, 4u, 8u, 16u}) {
    SCOPED_TRACE(block);
    MergeOptions options;
    options.block_cubes = block;
    const Extracted e = extract_both(volume, 0.0f, kClosed, options);
    expect_same_topology(e);
    expect_within_epsilon(e, options.epsilon_voxels);
    std::size_t largest = 0;
    for (std::size_t k = 0; k < e.stats.blocks_merged.size(); ++k) {
      if (e.stats.blocks_merged[k] > 0) largest = k;
    }
    EXPECT_EQ(std::size_t{1} << largest, std::min(block, 8u));  // no 16-block is that flat
    for (std::size_t k = std::bit_width(block); k < e.stats.blocks_merged.size(); ++k) {
      EXPECT_EQ(e.stats.blocks_merged[k], 0u);
    }
  }
}

// ---- A bound in millimetres ------------------------------------------------------------------

// epsilon_mm: the bound holds in patient millimetres, two-sided over both whole surfaces,
// on thick, sheared slices (as a gantry-tilted CT), for every block size up to 32; larger
// bounds and blocks merge more; marching cubes' topology, no crossings as written.
TEST(TypeMerging, BoundInMillimetresHoldsOnShearedThickSlices) {
  IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0.9, 2.5}}};  // sheared: z steps move along y
  std::vector<Volume> volumes;
  volumes.push_back(sphere_volume(kSanitized ? 24 : 40, kSanitized ? 10.2 : 17.3, 12.1,
                                  kSanitized ? 11.6 : 19.6, 11.4));
  for (unsigned seed = 1; seed <= (kSanitized ? 1u : 3u); ++seed) {
    volumes.push_back(blob_volume(seed, 0.4));
  }
  for (Volume& volume : volumes) volume.set_geometry(geometry);
  for (std::size_t v = 0; v < volumes.size(); ++v) {
    std::map<double, std::size_t> triangles;  // by bound, with blocks of 32
    for (const double epsilon_mm : {0.5, 1.0, 2.0}) {
      for (unsigned block : {8u, 32u}) {
        SCOPED_TRACE(testing::Message() << "volume " << v << " epsilon " << epsilon_mm
                                        << " mm, blocks " << block);
        MergeOptions options;
        options.epsilon_mm = epsilon_mm;
        options.block_cubes = block;
        Extracted e = extract_both(volumes[v], 0.0f, kClosed, options);
        expect_same_topology(e);
        TriangleMesh mc = e.mc;
        TriangleMesh tm = e.tm;
        to_patient(mc, geometry);
        to_patient(tm, geometry);
        EXPECT_LE(surface_distance(mc, tm, kSanitized ? 0.4 : 0.15, 1).hausdorff(),
                  epsilon_mm + 1e-3);
        EXPECT_TRUE(find_self_intersections(tm).pairs.empty());
        EXPECT_EQ(check_mesh(tm).degenerate_triangles, 0u);
        if (block == 32u) triangles[epsilon_mm] = e.tm.triangles.size();
      }
    }
    EXPECT_LT(triangles[2.0], triangles[0.5]);
  }
}

// With epsilon_mm, epsilon_voxels is ignored, and the bound holds.
TEST(TypeMerging, BoundInMillimetresReplacesTheVoxelBound) {
  Volume volume = blob_volume(2, 0.4);
  IndexToPatient geometry;
  geometry.axes = {{{1.2, 0, 0}, {0, 1.2, 0}, {0, 0, 2.0}}};
  volume.set_geometry(geometry);
  MergeOptions a;
  a.epsilon_mm = 0.7;
  MergeOptions b = a;
  b.epsilon_voxels = 3.0;
  const Extracted ea = extract_both(volume, 0.0f, kClosed, a);
  const Extracted eb = extract_both(volume, 0.0f, kClosed, b);
  EXPECT_EQ(ea.tm.triangles, eb.tm.triangles);
  EXPECT_EQ(ea.tm.positions, eb.tm.positions);
  TriangleMesh mc = ea.mc;
  TriangleMesh tm = ea.tm;
  to_patient(mc, geometry);
  to_patient(tm, geometry);
  EXPECT_LE(surface_distance(mc, tm, 0.2, 1).hausdorff(), 0.7 + 1e-3);
  EXPECT_LT(ratio(ea), 0.9);
}

TEST(TypeMerging, RejectsBadOptions) {
  const Volume volume = sphere_volume(10, 3.3, 4.4, 4.7, 4.2);
  MergeOptions options;
  options.block_cubes = 6;
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
  options.block_cubes = 1;
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
  options = {};
  options.epsilon_voxels = -1;
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
  options = {};
  options.block_cubes = 64;
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
  options = {};
  options.epsilon_mm = -0.5;
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
  options.epsilon_mm = std::numeric_limits<double>::infinity();
  EXPECT_THROW(extract_type_merged(volume, 0.0f, kClosed, options), std::invalid_argument);
}

TEST(TypeMerging, EmptyVolumeGivesEmptyMesh) {
  const Volume volume = sample_volume(5, 5, 5, [](double, double, double) { return 0.0; });
  MergeStats stats;
  const TriangleMesh mesh = extract_type_merged(volume, 1.0f, kClosed, {}, &stats);
  EXPECT_TRUE(mesh.empty());
  EXPECT_EQ(stats.triangles_before, 0u);
}

}  // namespace
}  // namespace typemerge::core
