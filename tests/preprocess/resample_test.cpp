// Resampling: exact sizes, spacing and origin; linear fields in patient mm reproduced exactly.
#include "preprocess/resample.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "preprocess_test_volumes.h"

namespace typemerge::preprocess {
namespace {

using core::Vec3;
using core::Volume;
using test::patient_field;
using test::spacing_geometry;

double ramp(const Vec3& p) { return 0.3 * p[0] - 0.2 * p[1] + 0.5 * p[2] + 7; }

// Every output voxel holds the ramp at its own patient position.
void expect_ramp(const Volume& volume, double tolerance) {
  const auto& s = volume.size();
  double worst = 0;
  for (std::int64_t k = 0; k < s.nz; ++k) {
    for (std::int64_t j = 0; j < s.ny; ++j) {
      for (std::int64_t i = 0; i < s.nx; ++i) {
        const Vec3 p = volume.geometry().apply(static_cast<double>(i), static_cast<double>(j),
                                               static_cast<double>(k));
        worst = std::max(worst, std::abs(volume.at(i, j, k) - ramp(p)));
      }
    }
  }
  EXPECT_LE(worst, tolerance);
}

TEST(Resample, IsotropicGivesExactSizesSpacingAndOrigin) {
  const auto geometry = spacing_geometry(0.7, 0.7, 2.5, {-12.5, 30, 101});
  const Volume volume = patient_field({40, 30, 12}, geometry, ramp);
  const StepResult result = resample_isotropic(volume);  // smallest spacing: 0.7 mm
  // n' = floor((n − 1)·s/s') + 1: 40, 30 and floor(11·2.5/0.7) + 1 = 40.
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{40, 30, 40}));
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(result.volume.geometry().spacing(axis), 0.7, 1e-12);
  }
  EXPECT_EQ(result.volume.geometry().origin, geometry.origin);
  EXPECT_EQ(result.record.step, "resample_isotropic");
  EXPECT_EQ(result.record.size_after, result.volume.size());
  expect_ramp(result.volume, 1e-4);
}

TEST(Resample, ReproducesALinearRampAtAGivenVoxelSize) {
  const auto geometry = spacing_geometry(0.8, 0.6, 2.0, {-5, 3, 10});
  const Volume volume = patient_field({33, 41, 15}, geometry, ramp);
  const StepResult result = resample(volume, {.voxel_size_mm = {0.45, 0.9, 1.1}});
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{57, 27, 26}));
  EXPECT_NEAR(result.volume.geometry().spacing(0), 0.45, 1e-12);
  EXPECT_NEAR(result.volume.geometry().spacing(1), 0.9, 1e-12);
  EXPECT_NEAR(result.volume.geometry().spacing(2), 1.1, 1e-12);
  EXPECT_EQ(result.volume.geometry().origin, geometry.origin);
  expect_ramp(result.volume, 1e-4);
  // Not a no-op: the values differ from the input's at the same index.
  EXPECT_GT(std::abs(result.volume.at(5, 5, 5) - volume.at(5, 5, 5)), 1.0f);
}

// Gantry tilt: the slice step has a component along y. Axes keep their directions.
TEST(Resample, KeepsASheredGeometry) {
  core::IndexToPatient geometry;
  geometry.origin = {10, -20, 30};
  const double tilt = 12.0 * M_PI / 180.0;
  geometry.axes = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 2.5 * std::sin(tilt), 2.5 * std::cos(tilt)}}};
  const Volume volume = patient_field({20, 24, 10}, geometry, ramp);
  const StepResult result = resample(volume, {.voxel_size_mm = {0.5, 0.5, 0.5}});
  const auto& axes = result.volume.geometry().axes;
  for (int axis = 0; axis < 3; ++axis) {
    const double scale = 0.5 / geometry.spacing(axis);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(axes[axis][c], geometry.axes[axis][c] * scale, 1e-12);
  }
  EXPECT_EQ(result.volume.geometry().origin, geometry.origin);
  EXPECT_EQ(result.volume.size().nz, 46);  // floor(9·2.5/0.5) + 1
  expect_ramp(result.volume, 1e-4);
}

TEST(Downsample, FactorTwoHalvesSizesAndKeepsEveryOtherVoxel) {
  const auto geometry = spacing_geometry(0.5, 0.5, 1.25, {1, 2, 3});
  const Volume volume = patient_field({64, 48, 20}, geometry,
                                      [](const Vec3& p) { return std::sin(p[0]) + p[1] * p[2]; });
  const StepResult result = downsample(volume, {.factor = 2});
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{32, 24, 10}));
  EXPECT_NEAR(result.volume.geometry().spacing(0), 1.0, 1e-12);
  EXPECT_NEAR(result.volume.geometry().spacing(2), 2.5, 1e-12);
  EXPECT_EQ(result.volume.geometry().origin, geometry.origin);
  for (std::int64_t k = 0; k < 10; ++k) {
    for (std::int64_t j = 0; j < 24; ++j) {
      for (std::int64_t i = 0; i < 32; ++i) {
        ASSERT_EQ(result.volume.at(i, j, k), volume.at(2 * i, 2 * j, 2 * k));
      }
    }
  }
  EXPECT_EQ(result.record.step, "downsample");
  EXPECT_EQ(*result.record.parameter("factor"), "2");
}

TEST(Downsample, OddSizesKeepTheLastVoxelWhenItFalls) {
  const Volume volume({5, 4, 1}, spacing_geometry(1, 1, 1));
  EXPECT_EQ(downsample(volume, {.factor = 2}).volume.size(), (core::VolumeSize{3, 2, 1}));
  EXPECT_EQ(downsample(volume, {.factor = 1}).volume.size(), volume.size());
}

// Given with std::move, the input's storage is released in 2 MiB blocks as its slices are
// read for the last time: the result must equal the const overload's, for int16 and float
// input, slices repeated (upsampling along k) or skipped (downsampling). 160×128×120 int16
// samples are 4.7 MiB (float: 9.4 MiB), so blocks go mid-volume.
TEST(Resample, AMovedInputGivesTheSameResult) {
  for (const bool as_int16 : {true, false}) {
    Volume volume = Volume::uninitialized({160, 128, 120}, spacing_geometry(0.8, 0.8, 2.5),
                                          core::SampleType::int16);
    std::uint32_t state = 7;
    for (auto& v : volume.int16_samples()) {
      state = state * 1664525u + 1013904223u;
      v = static_cast<std::int16_t>(static_cast<int>(state >> 20) - 2048);
    }
    if (!as_int16) volume.to_float();
    for (const double size : {1.0, 0.9, 3.3}) {
      const StepResult kept = resample_isotropic(volume, {.voxel_size_mm = size});
      Volume copy = volume;
      const StepResult moved = resample_isotropic(std::move(copy), {.voxel_size_mm = size});
      EXPECT_EQ(copy.size().voxels(), 0);
      ASSERT_EQ(kept.volume.size(), moved.volume.size());
      ASSERT_GT(moved.volume.size().voxels(), 0);
      EXPECT_EQ(0, std::memcmp(kept.volume.samples().data(), moved.volume.samples().data(),
                               kept.volume.sample_bytes()))
          << (as_int16 ? "int16" : "float") << " input, " << size << " mm";
      EXPECT_EQ(kept.record.description, moved.record.description);
    }
  }
}

TEST(Resample, RejectsInvalidParameters) {
  const Volume volume({4, 4, 4}, spacing_geometry(1, 1, 1));
  EXPECT_THROW(resample(volume, {.voxel_size_mm = {1, 0, 1}}), std::invalid_argument);
  EXPECT_THROW(resample(volume, {.voxel_size_mm = {-1, 1, 1}}), std::invalid_argument);
  EXPECT_THROW(resample_isotropic(volume, {.voxel_size_mm = -0.5}), std::invalid_argument);
  EXPECT_THROW(downsample(volume, {.factor = 0}), std::invalid_argument);
  EXPECT_THROW(resample(volume, {.voxel_size_mm = {1e-6, 1e-6, 1e-6}}), std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::preprocess
