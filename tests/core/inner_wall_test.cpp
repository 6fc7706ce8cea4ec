// The inner wall of a hollowed ball, checked independently of how it was made: closed and
// manifold with the outer wall (check_mesh), no crossing between the walls (CGAL's exact
// predicates, self_intersections.h), wall thickness by point-to-triangle distances from
// points spread over the inner wall to the outer one, and the enclosed volumes analytically.
#include "core/inner_wall.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"

namespace typemerge::core {
namespace {

struct Ball {
  Vec3 centre;
  double radius;
};

// max over the balls of R − |p − c| (mm), iso 0, on a grid of the given spacing.
Volume balls_volume(VolumeSize size, const std::array<double, 3>& h, const std::vector<Ball>& balls) {
  IndexToPatient geometry;
  geometry.origin = {-3.0, 5.0, -7.0};
  geometry.axes = {{{h[0], 0, 0}, {0, h[1], 0}, {0, 0, h[2]}}};
  Volume volume(size, geometry);
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 0; i < size.nx; ++i) {
        const Vec3 p = geometry.apply(double(i), double(j), double(k));
        double value = -1e9;
        for (const Ball& b : balls) {
          value = std::max(value, b.radius - std::hypot(p[0] - b.centre[0], p[1] - b.centre[1],
                                                        p[2] - b.centre[2]));
        }
        volume.at(i, j, k) = static_cast<float>(value);
      }
    }
  }
  return volume;
}

TriangleMesh outer_surface(const Volume& volume) {
  TriangleMesh mesh = extract_isosurface(volume, 0.0f);
  to_patient(mesh, volume.geometry());
  return mesh;
}

TriangleMesh joined(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh mesh = a;
  const auto offset = static_cast<std::uint32_t>(a.positions.size());
  mesh.positions.insert(mesh.positions.end(), b.positions.begin(), b.positions.end());
  mesh.normals.insert(mesh.normals.end(), b.normals.begin(), b.normals.end());
  for (const auto& t : b.triangles) mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  return mesh;
}

struct Thickness {
  double min = 0, mean = 0;
};

// From points spread over the inner wall (every 0.2 mm) to the outer wall's triangles.
Thickness wall_thickness(const TriangleMesh& inner, const TriangleMesh& outer) {
  const TriangleMesh samples = surface_samples(inner, 0.2);
  const std::vector<float> d = point_to_mesh_distances(samples.positions, outer, 2);
  Thickness t{1e9, 0};
  for (float v : d) {
    t.min = std::min(t.min, double(v));
    t.mean += v;
  }
  t.mean /= static_cast<double>(d.size());
  return t;
}

struct Grid {
  const char* name;
  std::array<double, 3> spacing;
  double min_share;  // of the wall the thinnest point must reach
};

// A ball of radius 12 mm hollowed to 3 mm: the inner wall is the ball of radius 9 mm.
TEST(InnerWall, HollowBallIsAClosedShellOfTheWallThickness) {
  const double radius = 12, wall = 3;
  // <= 1 mm voxels: at least 0.9 × the wall everywhere (issue 16). Coarser (2 × 2 × 3 mm): at
  // least 0.8 × (the tolerance the README states for coarse grids).
  for (const Grid& grid : {Grid{"1 mm", {1, 1, 1}, 0.9}, Grid{"0.6 × 0.8 × 1 mm", {0.6, 0.8, 1}, 0.9},
                           Grid{"2 × 2 × 3 mm", {2, 2, 3}, 0.8}}) {
    SCOPED_TRACE(grid.name);
    const double extent = 2 * radius + 6;
    const VolumeSize size{static_cast<std::int64_t>(extent / grid.spacing[0]) + 1,
                          static_cast<std::int64_t>(extent / grid.spacing[1]) + 1,
                          static_cast<std::int64_t>(extent / grid.spacing[2]) + 1};
    const Vec3 centre = {-3 + 0.5 * extent + 0.13, 5 + 0.5 * extent - 0.21, -7 + 0.5 * extent + 0.07};
    const Volume volume = balls_volume(size, grid.spacing, {{centre, radius}});
    const TriangleMesh outer = outer_surface(volume);
    InnerWallOptions options;
    options.wall_mm = wall;
    options.outer_deviation_mm = 0;
    InnerWallStats stats;
    const TriangleMesh inner = extract_inner_wall(volume, 0.0f, outer, options, &stats);
    ASSERT_FALSE(inner.empty());
    EXPECT_EQ(stats.components, 1u);
    EXPECT_EQ(stats.dropped_outside + stats.dropped_small, 0u);

    const TriangleMesh shell = joined(outer, inner);
    const MeshCheck check = check_mesh(shell);
    EXPECT_TRUE(check.closed_manifold());
    EXPECT_EQ(check.components, 2u);
    // The wall is extracted r²/(8 · wall) deeper (inner_wall.h), r the voxel diagonal.
    const double r2 = grid.spacing[0] * grid.spacing[0] + grid.spacing[1] * grid.spacing[1] +
                      grid.spacing[2] * grid.spacing[2];
    const double inner_volume =
        4.0 / 3.0 * std::numbers::pi * std::pow(radius - wall - r2 / (8 * wall), 3);
    // Marching cubes' chords cut into the ball: by up to 11 % on the coarse grid.
    EXPECT_NEAR(stats.hollow_volume_mm3, inner_volume,
                (grid.min_share < 0.9 ? 0.12 : 0.04) * inner_volume);
    EXPECT_NEAR(check.volume, check_mesh(outer).volume - stats.hollow_volume_mm3, 1e-6 * check.volume);
    EXPECT_TRUE(find_self_intersections(shell).pairs.empty());

    const Thickness t = wall_thickness(inner, outer);
    std::cout << "[ hollow  ] " << grid.name << ": wall " << wall << " mm, thickness min "
              << t.min << " mean " << t.mean << " mm, band samples " << stats.band_samples << "\n";
    EXPECT_GE(t.min, grid.min_share * wall);
    EXPECT_LE(t.mean, wall + 0.6 * grid.spacing[2]);
  }
}

// In slabs of cube layers (the default) the wall is the whole-volume computation's, byte for
// byte: slabs of 1, 2, 3, 7 and 16 layers on balls spread along z (so that pieces join across
// slab seams and distances reach across slabs), anisotropic and sheared grids, with and
// without normals, one and two threads, float and int16 samples.
TEST(InnerWall, SlabsGiveTheWholeVolumesBytes) {
  for (const bool sheared : {false, true}) {
    SCOPED_TRACE(sheared ? "sheared" : "orthogonal");
    Volume volume = balls_volume({28, 24, 46}, {0.9, 0.8, 0.6},
                                 {{{9, 14, 3}, 7.5}, {{12, 16, 12}, 6}, {{6, 13, 15}, 4}});
    if (sheared) {
      IndexToPatient g = volume.geometry();
      g.axes[2] = {0.05, -0.08, 0.6};  // a gantry tilt
      volume.set_geometry(g);
    }
    for (const bool as_int16 : {false, true}) {
      Volume field = volume;
      if (as_int16) {
        for (float& v : field.samples()) v = std::round(v * 100.0f) + 0.0f;  // 0.01 mm; no −0
        ASSERT_TRUE(field.to_int16_if_exact());
      }
      TriangleMesh outer = extract_isosurface(field, 0.0f, {.vertex_normals = true});
      to_patient(outer, field.geometry());
      for (const bool normals : {true, false}) {
        if (!normals) outer.normals.clear();
        InnerWallOptions options;
        options.wall_mm = 2;
        options.outer_deviation_mm = 0.9;
        options.slab_layers = 0;
        InnerWallStats whole_stats;
        const TriangleMesh whole = extract_inner_wall(field, 0.0f, outer, options, &whole_stats);
        ASSERT_GT(whole.triangles.size(), 500u);
        for (const std::int64_t layers : {1, 2, 3, 7, 16}) {
          for (const unsigned threads : {1u, 2u}) {
            options.slab_layers = layers;
            options.threads = threads;
            InnerWallStats stats;
            const TriangleMesh slabs = extract_inner_wall(field, 0.0f, outer, options, &stats);
            ASSERT_EQ(slabs.positions, whole.positions) << layers << " layers";
            ASSERT_EQ(slabs.normals, whole.normals) << layers << " layers";
            ASSERT_EQ(slabs.triangles, whole.triangles) << layers << " layers";
            EXPECT_EQ(stats.band_samples, whole_stats.band_samples);
            EXPECT_EQ(stats.components, whole_stats.components);
            EXPECT_EQ(stats.hollow_volume_mm3, whole_stats.hollow_volume_mm3);
          }
        }
      }
    }
  }
}

// The wall has vertex normals, pointing into the hollow, when the outer surface has them, and
// none when it has none (convert extracts without): the joined surface is uniform.
TEST(InnerWall, NormalsFollowTheOuterSurface) {
  const Vec3 centre = {-3 + 15.13, 5 + 14.79, -7 + 15.07};  // the grid's middle
  const Volume volume = balls_volume({31, 31, 31}, {1, 1, 1}, {{centre, 12}});
  TriangleMesh outer = outer_surface(volume);
  InnerWallOptions options;
  options.wall_mm = 3;
  const TriangleMesh with = extract_inner_wall(volume, 0.0f, outer, options);
  ASSERT_FALSE(with.empty());
  ASSERT_EQ(with.normals.size(), with.positions.size());
  for (std::size_t v = 0; v < with.positions.size(); ++v) {
    double outward = 0;  // along the radius: negative, into the hollow
    for (int a = 0; a < 3; ++a) outward += with.normals[v][a] * (with.positions[v][a] - centre[a]);
    EXPECT_LT(outward, 0.0);
  }
  outer.normals.clear();
  const TriangleMesh without = extract_inner_wall(volume, 0.0f, outer, options);
  EXPECT_TRUE(without.normals.empty());
  EXPECT_EQ(without.positions, with.positions);
  EXPECT_EQ(without.triangles, with.triangles);
}

// The outer surface lost a ball the mask still holds (--min-component, --keep-largest): its
// inner wall would be a cavity in empty space, and is dropped.
TEST(InnerWall, DropsTheWallOfAComponentTheOuterSurfaceLost) {
  const Vec3 big = {12, 20, 8}, small = {30, 20, 8};
  const Volume volume = balls_volume({46, 36, 30}, {1, 1, 1}, {{big, 10}, {small, 6}});
  const TriangleMesh outer = outer_surface(balls_volume({46, 36, 30}, {1, 1, 1}, {{big, 10}}));
  InnerWallOptions options;
  options.wall_mm = 2;
  InnerWallStats stats;
  const TriangleMesh inner = extract_inner_wall(volume, 0.0f, outer, options, &stats);
  EXPECT_EQ(stats.components, 2u);
  EXPECT_EQ(stats.dropped_outside, 1u);
  EXPECT_TRUE(check_mesh(joined(outer, inner)).closed_manifold());
  const double hollow = 4.0 / 3.0 * std::numbers::pi * std::pow(10 - 2 - 3.0 / 16, 3);
  EXPECT_NEAR(stats.hollow_volume_mm3, hollow, 0.05 * hollow);
}

// A solid nowhere thicker than twice the wall has no inner wall; a hollow smaller than wall³
// is dropped.
TEST(InnerWall, ThinPartsStaySolid) {
  const Volume volume = balls_volume({24, 24, 24}, {1, 1, 1}, {{{8, 13, 3}, 4.5}});
  const TriangleMesh outer = outer_surface(volume);
  InnerWallOptions options;
  options.wall_mm = 5;
  InnerWallStats stats;
  EXPECT_TRUE(extract_inner_wall(volume, 0.0f, outer, options, &stats).empty());
  options.wall_mm = 3.2;  // inner radius 1.3 mm: 9 mm³ < 3.2³
  EXPECT_TRUE(extract_inner_wall(volume, 0.0f, outer, options, &stats).empty());
  EXPECT_EQ(stats.dropped_small, stats.components);
}

}  // namespace
}  // namespace typemerge::core
