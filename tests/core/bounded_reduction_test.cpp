// extract_type_merged_to_count and extract_type_merged_within (core/bounded_reduction.h): the
// count window, the bound the surface keeps, the cap, the collapses where merging alone cannot
// reach the count, and the locally limited collapses within a bound alone.
#include "core/bounded_reduction.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

// Gaussian blobs on 0.8 × 0.8 × 2 mm voxels.
Volume blobs() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(4.0, 28.0);
  std::array<std::array<double, 3>, 7> centres{};
  for (auto& c : centres) c = {u(rng), u(rng), u(rng)};
  Volume volume = test::sample_volume(32, 32, 32, [&](double x, double y, double z) {
    double f = 0.0;
    for (const auto& c : centres) {
      f += std::exp(-((x - c[0]) * (x - c[0]) + (y - c[1]) * (y - c[1]) + (z - c[2]) * (z - c[2])) /
                    20.0);
    }
    return f - 0.4;
  });
  IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0, 2.0}}};
  volume.set_geometry(geometry);
  return volume;
}

ExtractOptions one_thread() {
  ExtractOptions extract;
  extract.threads = 1;
  extract.vertex_normals = false;
  return extract;
}

// The reduced surface (index space) within `bound` mm of marching cubes' surface, sampled over
// both, closed and manifold with marching cubes' topology and no crossing pair.
void expect_sound_within(const Volume& volume, const TriangleMesh& reduced, double bound) {
  TriangleMesh mc = extract_isosurface(volume, 0.0f, one_thread());
  TriangleMesh tm = reduced;
  to_patient(mc, volume.geometry());
  to_patient(tm, volume.geometry());
  EXPECT_LE(surface_distance(mc, tm, 0.2, 1).hausdorff(), bound + 1e-3);
  const MeshCheck a = check_mesh(mc);
  const MeshCheck b = check_mesh(tm);
  EXPECT_TRUE(b.closed_manifold());
  EXPECT_EQ(a.euler_characteristic, b.euler_characteristic);
  EXPECT_EQ(a.components, b.components);
  EXPECT_TRUE(find_self_intersections(tm).pairs.empty());
}

TEST(BoundedReduction, MeetsTheCountWithinItsBound) {
  const Volume volume = blobs();
  const TriangleMesh mc_index = extract_isosurface(volume, 0.0f, one_thread());
  for (const double share : {0.5, 0.3, 0.1}) {
    SCOPED_TRACE(share);
    const auto target = static_cast<std::size_t>(share * double(mc_index.triangles.size()));
    const ReductionResult r =
        extract_type_merged_to_count(volume, 0.0f, one_thread(), {}, target, 8.0);
    EXPECT_TRUE(r.target_met) << r.mesh.triangles.size() << " for " << target;
    EXPECT_LE(r.mesh.triangles.size(), target);
    EXPECT_GE(double(r.mesh.triangles.size()), 0.99 * double(target));
    EXPECT_GT(r.bound_mm, 0.0);
    EXPECT_LE(r.bound_mm, 8.0);
    EXPECT_LE(r.tries, 24u);
    expect_sound_within(volume, r.mesh, r.bound_mm);
  }
}

// Merging alone leaves more than 10 triangles at 1 mm: the merge and collapses within half the
// cap, then within the cap, go as far as the bound allows and say the target was missed.
TEST(BoundedReduction, ACountOutOfReachCollapsesAsFarAsTheCapAllows) {
  const Volume volume = blobs();
  const ReductionResult r = extract_type_merged_to_count(volume, 0.0f, one_thread(), {}, 10, 1.0);
  EXPECT_FALSE(r.target_met);
  EXPECT_EQ(r.bound_mm, 1.0);
  EXPECT_EQ(r.tries, 2u);
  EXPECT_GT(r.collapse.collapses, 0u);
  EXPECT_GT(r.mesh.triangles.size(), 10u);
  MergeOptions at_cap;
  at_cap.epsilon_mm = 1.0;
  const TriangleMesh merged = extract_type_merged(volume, 0.0f, one_thread(), at_cap);
  EXPECT_EQ(r.mesh.triangles.size(), merged.triangles.size() - 2 * r.collapse.collapses);
  expect_sound_within(volume, r.mesh, 1.0);
}

// Within a bound alone: the merge, then collapses within the same bound, each within a tenth
// of it locally: fewer triangles than the merge, sound within the bound, and fewer collapses
// than the bound alone would allow.
TEST(BoundedReduction, WithinABoundCollapsesTheMergeLocallyLimited) {
  const Volume volume = blobs();
  for (const double bound : {0.5, 2.0}) {
    SCOPED_TRACE(bound);
    const ReductionResult r = extract_type_merged_within(volume, 0.0f, one_thread(), {}, bound);
    MergeOptions merge;
    merge.epsilon_mm = bound;
    const TriangleMesh merged = extract_type_merged(volume, 0.0f, one_thread(), merge);
    EXPECT_TRUE(r.target_met);
    EXPECT_EQ(r.bound_mm, bound);
    EXPECT_EQ(r.tries, 1u);
    EXPECT_GT(r.collapse.collapses, 0u);
    EXPECT_GT(r.collapse.passed_over_local_error, 0u);
    EXPECT_EQ(r.mesh.triangles.size(), merged.triangles.size() - 2 * r.collapse.collapses);
    expect_sound_within(volume, r.mesh, bound);
    // Within a bound the collapses move kept vertices (placement), in index space as the merge
    // writes; to a count they move none.
    const std::set<std::array<float, 3>> input(merged.positions.begin(), merged.positions.end());
    auto moved = [&](const TriangleMesh& mesh) {
      return std::count_if(mesh.positions.begin(), mesh.positions.end(),
                           [&](const auto& p) { return input.count(p) == 0; });
    };
    EXPECT_GT(moved(r.mesh), 0);
    TriangleMesh exhausted = merged;
    const CollapseStats all = collapse_to_count(volume, 0.0f, one_thread(), exhausted, 0, bound);
    EXPECT_LT(r.collapse.collapses, all.collapses);
    EXPECT_EQ(moved(exhausted), 0);
  }
  EXPECT_THROW(extract_type_merged_within(volume, 0.0f, one_thread(), {}, 0.0),
               std::invalid_argument);
  EXPECT_THROW(extract_type_merged_within(volume, 0.0f, one_thread(), {}, INFINITY),
               std::invalid_argument);
}

// options.slices_done is said once, with every slice, when the volume is read no more: the
// callback wipes the samples (every one outside), and each reduction's surface is still the
// one made from the whole volume, so no extraction came after it. Each kind of end: the bound
// alone (its collapses), a count reached by bisection, and one out of the merge's reach (the
// collapses at half the cap, then at the cap).
TEST(BoundedReduction, SaysOnceWhenTheVolumeIsReadNoMore) {
  const Volume volume = blobs();
  using Reduce = std::function<ReductionResult(const Volume&, const MergeOptions&)>;
  const std::vector<std::pair<const char*, Reduce>> reductions{
      {"within 0.5 mm",
       [](const Volume& v, const MergeOptions& o) {
         return extract_type_merged_within(v, 0.0f, one_thread(), o, 0.5);
       }},
      {"a third of the triangles",
       [](const Volume& v, const MergeOptions& o) {
         const std::size_t mc = extract_isosurface(v, 0.0f, one_thread()).triangles.size();
         return extract_type_merged_to_count(v, 0.0f, one_thread(), o, mc / 3, 8.0);
       }},
      {"out of reach",
       [](const Volume& v, const MergeOptions& o) {
         return extract_type_merged_to_count(v, 0.0f, one_thread(), o, 10, 1.0);
       }},
  };
  for (const auto& [name, reduce] : reductions) {
    SCOPED_TRACE(name);
    const ReductionResult kept = reduce(volume, {});
    Volume wiped = volume;
    int calls = 0;
    MergeOptions options;
    options.slices_done = [&](std::int64_t begin, std::int64_t end) {
      ++calls;
      EXPECT_EQ(begin, 0);
      EXPECT_EQ(end, wiped.size().nz);
      std::fill(wiped.samples().begin(), wiped.samples().end(), -1.0f);
    };
    const ReductionResult r = reduce(wiped, options);
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(std::as_const(wiped).at(16, 16, 16), -1.0f);
    EXPECT_GT(r.mesh.triangles.size(), 0u);
    EXPECT_EQ(r.mesh.triangles, kept.mesh.triangles);
    EXPECT_EQ(r.mesh.positions, kept.mesh.positions);
    EXPECT_EQ(r.tries, kept.tries);
  }
}

TEST(BoundedReduction, RejectsBadArguments) {
  const Volume volume = blobs();
  EXPECT_THROW(extract_type_merged_to_count(volume, 0.0f, one_thread(), {}, 0, 1.0),
               std::invalid_argument);
  EXPECT_THROW(extract_type_merged_to_count(volume, 0.0f, one_thread(), {}, 100, 0.0),
               std::invalid_argument);
  EXPECT_THROW(extract_type_merged_to_count(volume, 0.0f, one_thread(), {}, 100, NAN),
               std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::core
