// collapse_within_bound (core/bounded_collapse.h): every guarantee of the header, on merged
// surfaces of synthetic volumes, and the refusals that keep them.
#include "core/bounded_collapse.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/type_merging.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

ExtractOptions one_thread() {
  ExtractOptions extract;
  extract.threads = 1;
  extract.vertex_normals = false;
  return extract;
}

// Marching cubes' surface and type merging's at `bound_mm`, both in patient mm.
struct Surfaces {
  TriangleMesh mc;
  TriangleMesh merged;
};
Surfaces surfaces_of(const Volume& volume, float iso, double bound_mm) {
  Surfaces s;
  s.mc = extract_isosurface(volume, iso, one_thread());
  MergeOptions merge;
  merge.epsilon_mm = bound_mm;
  s.merged = extract_type_merged(volume, iso, one_thread(), merge);
  to_patient(s.mc, volume.geometry());
  to_patient(s.merged, volume.geometry());
  return s;
}

// Gaussian blobs on sheared, anisotropic voxels.
Volume blobs(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(5.0, 27.0);
  std::array<std::array<double, 3>, 6> centres{};
  for (auto& c : centres) c = {u(rng), u(rng), u(rng)};
  Volume volume = test::sample_volume(32, 32, 32, [&](double x, double y, double z) {
    double f = 0.0;
    for (const auto& c : centres) {
      f += std::exp(-((x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) + (z - c[2]) * (z - c[2])) /
                    18.0);
    }
    return f - 0.4;
  });
  IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0.3, 2.0}}};
  volume.set_geometry(geometry);
  return volume;
}

// What the header promises of a collapsed surface against its reference.
void expect_guarantees(const TriangleMesh& reference, const TriangleMesh& before,
                       const TriangleMesh& after, double bound, bool moved = false) {
  const MeshCheck r = check_mesh(reference);
  const MeshCheck a = check_mesh(after);
  EXPECT_TRUE(a.closed_manifold());
  EXPECT_EQ(a.euler_characteristic, r.euler_characteristic);
  EXPECT_EQ(a.components, r.components);
  EXPECT_TRUE(find_self_intersections(after).pairs.empty());
  const ExtremeAngles ref_shapes = count_extreme_angles(before);
  const ExtremeAngles shapes = count_extreme_angles(after);
  EXPECT_LE(shapes.above_170, ref_shapes.above_170);
  EXPECT_LE(shapes.below_1, ref_shapes.below_1);
  EXPECT_LE(surface_distance(reference, after, 0.1, 1).hausdorff(), bound + 1e-3);
  if (moved) return;
  // Every vertex is one of the input's (without placement no vertex moves).
  std::set<std::array<float, 3>> input(before.positions.begin(), before.positions.end());
  for (const auto& p : after.positions) EXPECT_TRUE(input.count(p) == 1);
}

TEST(BoundedCollapse, ReachesTheTargetKeepingEveryGuarantee) {
  for (unsigned seed : {3u, 11u}) {
    SCOPED_TRACE(seed);
    const Volume volume = blobs(seed);
    const Surfaces s = surfaces_of(volume, 0.0f, 1.0);
    TriangleMesh collapsed = s.merged;
    const std::size_t target = s.mc.triangles.size() / 10;
    ASSERT_GT(s.merged.triangles.size(), target);
    const CollapseStats stats = collapse_within_bound(collapsed, s.mc, {1.5, target});
    remove_unreferenced_vertices(collapsed);
    EXPECT_GT(stats.collapses, 0u);
    EXPECT_LE(collapsed.triangles.size(), target);
    EXPECT_GE(collapsed.triangles.size() + 2, target);
    EXPECT_EQ(collapsed.triangles.size(), s.merged.triangles.size() - 2 * stats.collapses);
    expect_guarantees(s.mc, s.merged, collapsed, 1.5);
  }
}

TEST(BoundedCollapse, StopsWhereTheBoundStopsIt) {
  const Volume volume = blobs(5);
  const Surfaces s = surfaces_of(volume, 0.0f, 0.3);
  TriangleMesh collapsed = s.merged;
  const CollapseStats stats = collapse_within_bound(collapsed, s.mc, {0.3, 4});
  remove_unreferenced_vertices(collapsed);
  EXPECT_GT(stats.collapses, 0u);
  EXPECT_GT(collapsed.triangles.size(), 4u);  // a small bound cannot reach 4 triangles
  EXPECT_GT(stats.refused_distance, 0u);
  EXPECT_EQ(stats.held_reference_triangles, 0u);  // every one covered by parts
  expect_guarantees(s.mc, s.merged, collapsed, 0.3);
}

// Two wavy plates 1 mm thick, 1 mm apart, with a bound of 3 mm: chords across a trough of the
// lower plate's top would rise into the upper plate, closer than the bound to both surfaces;
// the crossing test must refuse them.
TEST(BoundedCollapse, CloseLayersDoNotCollapseIntoEachOther) {
  Volume volume = test::sample_volume(72, 40, 36, [](double x, double y, double z) {
    const double wave = 8.0 * std::sin(x / 6.0);  // voxels of 0.25 mm
    const double lower = 2.0 - std::abs(z - 12.0 - wave);
    const double upper = 2.0 - std::abs(z - 20.0 - wave);
    const double inside_square = std::min(std::min(x - 2.0, 69.0 - x), std::min(y - 2.0, 37.0 - y));
    return std::min(std::max(lower, upper), inside_square);
  });
  IndexToPatient geometry;
  geometry.axes = {{{0.25, 0, 0}, {0, 0.25, 0}, {0, 0, 0.25}}};
  volume.set_geometry(geometry);
  const Surfaces s = surfaces_of(volume, 0.0f, 0.5);
  TriangleMesh collapsed = s.merged;
  const CollapseStats stats = collapse_within_bound(collapsed, s.mc, {3.0, 0});
  remove_unreferenced_vertices(collapsed);
  EXPECT_GT(stats.collapses, 0u);
  EXPECT_GT(stats.refused_crossing, 0u);
  expect_guarantees(s.mc, s.merged, collapsed, 3.0);
}

// local_rms passes over the candidates whose quadric estimate exceeds it: fewer collapses
// than the bound alone allows, more the larger it is, every guarantee kept; a limit no
// candidate meets makes none.
TEST(BoundedCollapse, ALocalLimitStopsBeforeTheBound) {
  const Volume volume = blobs(11);
  const Surfaces s = surfaces_of(volume, 0.0f, 1.0);
  std::vector<std::size_t> collapses;
  for (const double local_rms : {0.0, 0.15, 0.05}) {
    SCOPED_TRACE(local_rms);
    TriangleMesh collapsed = s.merged;
    const CollapseStats stats = collapse_within_bound(collapsed, s.mc, {1.5, 0, local_rms});
    remove_unreferenced_vertices(collapsed);
    EXPECT_EQ(stats.passed_over_local_error > 0, local_rms > 0.0);
    EXPECT_EQ(collapsed.triangles.size(), s.merged.triangles.size() - 2 * stats.collapses);
    expect_guarantees(s.mc, s.merged, collapsed, 1.5);
    collapses.push_back(stats.collapses);
  }
  EXPECT_GT(collapses[2], 0u);
  EXPECT_LT(collapses[2], collapses[1]);
  EXPECT_LT(collapses[1], collapses[0]);
  TriangleMesh untouched = s.merged;
  const CollapseStats none = collapse_within_bound(untouched, s.mc, {1.5, 0, 1e-9});
  EXPECT_EQ(none.collapses, 0u);
  EXPECT_EQ(untouched.triangles, s.merged.triangles);
}

// A surface left open at the volume's border (close_borders off): the border's vertices are
// never collapsed away, so the border edges stay, with the topology and every other guarantee.
TEST(BoundedCollapse, AnOpenSurfaceKeepsItsBorder) {
  Volume volume = test::sample_volume(28, 28, 20, [](double x, double y, double z) {
    return 14.0 - std::hypot(x - 4.0, y - 6.0, z - 3.0) + std::sin(0.5 * x) * std::cos(0.4 * y);
  });
  IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0, 1.5}}};
  volume.set_geometry(geometry);
  ExtractOptions open = one_thread();
  open.close_borders = false;
  TriangleMesh mc = extract_isosurface(volume, 0.0f, open);
  MergeOptions merge;
  merge.epsilon_mm = 1.0;
  TriangleMesh merged = extract_type_merged(volume, 0.0f, open, merge);
  to_patient(mc, geometry);
  to_patient(merged, geometry);
  const MeshCheck before = check_mesh(merged);
  ASSERT_GT(before.boundary_edges, 0u);
  TriangleMesh collapsed = merged;
  for (const double local_rms : {0.0, 0.1, -1.0}) {  // -1: no local limit, with placement
    collapsed = merged;
    CollapseOptions options{1.0, 0, std::max(local_rms, 0.0)};
    options.move_vertices = local_rms < 0.0;  // in the surface's own frame
    const CollapseStats stats = collapse_within_bound(collapsed, mc, options);
    remove_unreferenced_vertices(collapsed);
    EXPECT_GT(stats.collapses, 0u);
    EXPECT_EQ(stats.overlay_proofs, 0u);  // it needs a closed reference
    const MeshCheck after = check_mesh(collapsed);
    EXPECT_EQ(after.boundary_edges, before.boundary_edges);
    EXPECT_EQ(after.non_manifold_edges, 0u);
    EXPECT_EQ(after.non_manifold_vertices, 0u);
    EXPECT_EQ(after.inconsistent_edges, 0u);
    EXPECT_EQ(after.euler_characteristic, before.euler_characteristic);
    EXPECT_EQ(after.components, before.components);
    EXPECT_TRUE(find_self_intersections(collapsed).pairs.empty());
    EXPECT_LE(surface_distance(mc, collapsed, 0.1, 1).hausdorff(), 1.0 + 1e-3);
  }
}

// Placement: the kept vertex moves to its quadric's point. Every guarantee holds at the moved
// positions, the frame's positions give exactly the surface checked (to_patient of them), and
// at the same count the surface lies nearer marching cubes' on average than with vertices
// kept where they were.
TEST(BoundedCollapse, PlacementMovesVerticesKeepingEveryGuarantee) {
  for (unsigned seed : {3u, 11u}) {
    SCOPED_TRACE(seed);
    const Volume volume = blobs(seed);
    TriangleMesh mc = extract_isosurface(volume, 0.0f, one_thread());
    to_patient(mc, volume.geometry());
    MergeOptions merge;
    merge.epsilon_mm = 1.0;
    const TriangleMesh merged = extract_type_merged(volume, 0.0f, one_thread(), merge);
    TriangleMesh patient = merged;
    to_patient(patient, volume.geometry());
    const std::size_t target = mc.triangles.size() / 8;

    TriangleMesh kept = patient;
    collapse_within_bound(kept, mc, {1.5, target});
    remove_unreferenced_vertices(kept);

    TriangleMesh frame = merged;  // index space
    TriangleMesh moved = patient;
    CollapseOptions options{1.5, target};
    options.move_vertices = true;
    options.geometry = &volume.geometry();
    options.frame = &frame.positions;
    const CollapseStats stats = collapse_within_bound(moved, mc, options);
    frame.triangles = moved.triangles;  // (the geometry's determinant is positive: no flip)
    EXPECT_GT(stats.collapses, 0u);
    // The frame, taken to patient space, is the surface checked, bit for bit.
    TriangleMesh again = frame;
    to_patient(again, volume.geometry());
    ASSERT_EQ(again.positions.size(), moved.positions.size());
    for (const auto& t : moved.triangles) {
      for (auto v : t) EXPECT_EQ(again.positions[v], moved.positions[v]);
    }
    remove_unreferenced_vertices(moved);
    std::set<std::array<float, 3>> input(patient.positions.begin(), patient.positions.end());
    const auto off_input = std::count_if(moved.positions.begin(), moved.positions.end(),
                                         [&](const auto& p) { return input.count(p) == 0; });
    EXPECT_GT(off_input, 0);
    EXPECT_EQ(moved.triangles.size(), kept.triangles.size());
    expect_guarantees(mc, patient, moved, 1.5, true);
    EXPECT_LT(surface_distance(mc, moved, 0.1, 1).mean(),
              surface_distance(mc, kept, 0.1, 1).mean());
  }
  const Volume volume = blobs(3);
  Surfaces s = surfaces_of(volume, 0.0f, 1.0);
  CollapseOptions no_frame{1.0, 0};
  no_frame.move_vertices = true;
  no_frame.geometry = &volume.geometry();
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, no_frame), std::invalid_argument);
}

// Marching cubes' surface of `volume` and its merge within `bound` (mm), the merge collapsed
// within the same bound with placement (in the volume's frame), all in patient mm.
struct Placed {
  TriangleMesh mc;
  TriangleMesh merged;
  TriangleMesh collapsed;
  CollapseStats stats;
};
Placed collapsed_with_placement(const Volume& volume, double bound) {
  Placed out;
  out.mc = extract_isosurface(volume, 0.0f, one_thread());
  to_patient(out.mc, volume.geometry());
  MergeOptions merge;
  merge.epsilon_mm = bound;
  TriangleMesh frame = extract_type_merged(volume, 0.0f, one_thread(), merge);
  out.merged = frame;
  to_patient(out.merged, volume.geometry());
  out.collapsed = out.merged;
  CollapseOptions options{bound, 0};
  options.move_vertices = true;
  options.geometry = &volume.geometry();
  options.frame = &frame.positions;
  out.stats = collapse_within_bound(out.collapsed, out.mc, options);
  remove_unreferenced_vertices(out.collapsed);
  return out;
}

// A bound of a quarter of the finest voxel, far below the merged triangles' size: the corner
// and centroid tests prove few new triangles there; the overlay proof (the reference beneath a
// triangle, projected onto it) proves most, and the sampled distance stays within the bound.
TEST(BoundedCollapse, TheOverlayProvesTrianglesFarLargerThanTheBound) {
  for (unsigned seed : {3u, 7u}) {
    SCOPED_TRACE(seed);
    const Placed p = collapsed_with_placement(blobs(seed), 0.2);
    EXPECT_GT(p.stats.overlay_proofs, p.stats.collapses);  // several new triangles a collapse
    EXPECT_LE(3 * p.collapsed.triangles.size(), p.merged.triangles.size());
    expect_guarantees(p.mc, p.merged, p.collapsed, 0.2, true);
  }
}

// A bound of a sixteenth of the finest voxel: reference triangles across an edge of the merge
// are within it of two merged triangles together but of neither alone (nor, split three
// levels, their parts); the overlay proof with the surface beneath them proves them, so they
// are not held, and the collapses keep every guarantee.
TEST(BoundedCollapse, TheOverlayProvesReferenceTrianglesNoSingleTriangleCovers) {
  const Placed p = collapsed_with_placement(blobs(3), 0.05);
  EXPECT_GT(p.stats.reference_overlay_proofs, 0u);
  EXPECT_GT(p.stats.collapses, 0u);
  EXPECT_LT(10 * p.stats.held_reference_triangles, p.mc.triangles.size());
  expect_guarantees(p.mc, p.merged, p.collapsed, 0.05, true);
}

TEST(BoundedCollapse, RejectsABadBound) {
  const Volume volume = blobs(3);
  Surfaces s = surfaces_of(volume, 0.0f, 1.0);
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, {0.0, 0}), std::invalid_argument);
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, {NAN, 0}), std::invalid_argument);
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, {INFINITY, 0}), std::invalid_argument);
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, {1.0, 0, -0.1}), std::invalid_argument);
  EXPECT_THROW(collapse_within_bound(s.merged, s.mc, {1.0, 0, NAN}), std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::core
