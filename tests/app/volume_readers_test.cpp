// make_surface's VolumeReaders (app/surface_pipeline.h): the volume is freed once the last
// surface made from it has read it for the last time, never before, and every surface is the
// one made from a volume kept whole.
#include "app/surface_pipeline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/test_volumes.h"

namespace typemerge::app {
namespace {

// A blob on 64 × 64 samples a slice (16 KiB: released slices span whole pages), 1 × 1 × 2 mm.
core::Volume blob() {
  core::Volume volume = core::test::sample_volume(64, 64, 24, [](double x, double y, double z) {
    return 400.0 - 30.0 * std::sqrt((x - 31.5) * (x - 31.5) + (y - 30.2) * (y - 30.2) +
                                    4.0 * (z - 11.7) * (z - 11.7)) +
           40.0 * std::sin(x * 0.4) * std::cos(y * 0.3 + z * 0.2);
  });
  core::IndexToPatient geometry;
  geometry.axes = {{{1.0, 0, 0}, {0, 1.0, 0}, {0, 0, 2.0}}};
  volume.set_geometry(geometry);
  return volume;
}

// Whether slice k's samples are gone (a slice on whole pages reads zeros, Linux).
bool released(const core::Volume& volume, std::int64_t k = 12) {
  return volume.at(20, 20, k) == 0.0f;
}

SurfaceSpec iso(double lo) {
  SurfaceSpec spec;
  spec.name = "iso";
  spec.label = "iso";
  spec.lo = lo;
  return spec;
}

struct Case {
  std::string name;
  SurfaceSpec spec;
  PipelineOptions options;
};

std::vector<Case> cases() {
  std::vector<Case> all;
  PipelineOptions base;
  base.threads = 2;
  all.push_back({"tm", iso(0.0), base});
  PipelineOptions mc = base;
  mc.algorithm = "mc";
  all.push_back({"mc", iso(0.0), mc});
  PipelineOptions within = base;
  within.finish.max_error_mm = 0.8;
  all.push_back({"--max-error", iso(0.0), within});
  PipelineOptions count = base;
  count.finish.reduce_to_triangles = 400;
  all.push_back({"--reduce-to", iso(0.0), count});
  SurfaceSpec window = iso(-100.0);
  window.name = "window";
  window.hi = 150.0;
  all.push_back({"window", window, base});
  PipelineOptions hollow = base;
  hollow.hollow_mm = 2.0;
  all.push_back({"--hollow", iso(0.0), hollow});
  PipelineOptions distance = within;
  distance.measure_distance = true;
  all.push_back({"--max-error, distance measured", iso(0.0), distance});
  return all;
}

TEST(VolumeReaders, ASliceIsFreedOnceEverySurfaceHasReadIt) {
  core::Volume volume = blob();
  const core::Volume whole = blob();
  VolumeReaders readers(volume, 2);
  readers.slices_read(0, 24);
  EXPECT_FALSE(released(volume, 12));
  readers.slices_read(10, 14);
  readers.slices_read(30, 40);  // beyond the slices: nothing
#if defined(__linux__)
  EXPECT_TRUE(released(volume, 11));
  EXPECT_TRUE(released(volume, 12));
#endif
  EXPECT_EQ(volume.at(20, 20, 9), whole.at(20, 20, 9));
  EXPECT_EQ(volume.at(20, 20, 14), whole.at(20, 20, 14));
  readers.slices_read(0, 10);
  readers.slices_read(14, 24);
#if defined(__linux__)
  for (std::int64_t k = 0; k < 24; ++k) EXPECT_TRUE(released(volume, k)) << k;
#endif
}

// One surface, each path: the same surface with readers, and the volume freed after it.
TEST(VolumeReaders, ASoleSurfaceFreesTheVolumeAndIsUnchanged) {
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const core::Volume volume = blob();
    const SurfaceResult kept = make_surface(volume, c.spec, c.options);
    ASSERT_GT(kept.mesh.triangles.size(), 0u);
    core::Volume freed = blob();
    VolumeReaders readers(freed, 1);
    const SurfaceResult result = make_surface(freed, c.spec, c.options, &readers);
    EXPECT_EQ(result.mesh.triangles, kept.mesh.triangles);
    EXPECT_EQ(result.mesh.positions, kept.mesh.positions);
    EXPECT_EQ(result.warnings, kept.warnings);
    ASSERT_EQ(result.distance.has_value(), kept.distance.has_value());
    if (kept.distance) {
      EXPECT_GT(kept.distance->mean_mm, 0.0);
      EXPECT_EQ(result.distance->max_mm, kept.distance->max_mm);
      EXPECT_EQ(result.distance->mean_mm, kept.distance->mean_mm);
      EXPECT_EQ(result.distance->finished_max_mm, kept.distance->finished_max_mm);
    }
#if defined(__linux__)
    EXPECT_TRUE(released(freed));
#endif
  }
}

// Two surfaces of one volume: the first leaves it whole for the second, which frees it.
TEST(VolumeReaders, TwoSurfacesFreeTheVolumeAfterTheSecond) {
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const core::Volume volume = blob();
    const SurfaceResult kept = make_surface(volume, c.spec, c.options);
    core::Volume shared = blob();
    VolumeReaders readers(shared, 2);
    const SurfaceResult first = make_surface(shared, c.spec, c.options, &readers);
    EXPECT_FALSE(released(shared));
    const SurfaceResult second = make_surface(shared, c.spec, c.options, &readers);
    for (const SurfaceResult* r : {&first, &second}) {
      EXPECT_EQ(r->mesh.triangles, kept.mesh.triangles);
      EXPECT_EQ(r->mesh.positions, kept.mesh.positions);
    }
#if defined(__linux__)
    EXPECT_TRUE(released(shared));
#endif
  }
}

TEST(VolumeReaders, ReadersOfAnotherVolumeAreRefused) {
  const core::Volume volume = blob();
  core::Volume other = blob();
  VolumeReaders readers(other, 1);
  EXPECT_THROW(make_surface(volume, iso(0.0), PipelineOptions{}, &readers), std::logic_error);
  EXPECT_FALSE(released(other));
}

}  // namespace
}  // namespace typemerge::app
