// Otsu's threshold: the rule on tiny histograms with known answers, OpenCV's own THRESH_OTSU
// (8-bit, written independently) as the oracle on volumes, and a CT-like and an MR-like volume.
#include "preprocess/otsu_threshold.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "preprocess_test_volumes.h"

namespace typemerge::preprocess {
namespace {

using test::patient_field;
using test::spacing_geometry;

TEST(OtsuSplit, TwoSpikesSplitBetweenThem) {
  // Counts 5 at bin 1 and 5 at bin 6: every split from 2 to 6 separates them equally well;
  // the middle one wins.
  std::vector<std::uint64_t> histogram(8, 0);
  histogram[1] = 5;
  histogram[6] = 5;
  EXPECT_EQ(detail::otsu_split(histogram), 4);
  // A third spike nearer the upper one joins it: splits 2 to 5 tie.
  histogram[5] = 5;
  EXPECT_EQ(detail::otsu_split(histogram), 4);
  // A heavy spike at 2 joins the lower class: splits 3 to 5.
  histogram[2] = 20;
  EXPECT_EQ(detail::otsu_split(histogram), 4);
  // No gap: one best split.
  const std::vector<std::uint64_t> ramp = {9, 8, 1, 1, 8, 9};
  EXPECT_EQ(detail::otsu_split(ramp), 3);
}

// A ball of `tissue` in `background`, with Gaussian noise.
core::Volume ball_volume(double background, double tissue, double noise, unsigned seed) {
  auto volume = patient_field({40, 36, 30}, spacing_geometry(1.0, 1.0, 2.0), [&](const core::Vec3& p) {
    return std::hypot(p[0] - 20, p[1] - 18, p[2] - 30) < 14 ? tissue : background;
  });
  test::add_gaussian_noise(volume, noise, seed);
  return volume;
}

// OpenCV's THRESH_OTSU on the voxels mapped linearly to 0..255: the threshold in volume units
// (OpenCV's class 1 is > t, so the edge is t + 1 in 8-bit units).
double opencv_otsu(const core::Volume& volume) {
  const auto [low, high] = std::minmax_element(volume.samples().begin(), volume.samples().end());
  const double lo = *low, scale = 255.0 / (*high - lo);
  cv::Mat bytes(1, static_cast<int>(volume.samples().size()), CV_8U);
  for (std::size_t v = 0; v < volume.samples().size(); ++v) {
    bytes.at<std::uint8_t>(static_cast<int>(v)) =
        cv::saturate_cast<std::uint8_t>((volume.samples()[v] - lo) * scale);
  }
  cv::Mat ignored;
  const double t = cv::threshold(bytes, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  return lo + (t + 1) / scale;
}

TEST(OtsuThreshold, CtLikeBallLandsBetweenAirAndSoftTissueAsOpenCvSays) {
  const auto volume = ball_volume(-1000, 40, 30, 1);
  const OtsuThreshold otsu = otsu_threshold(volume);
  // Anywhere in the gap between the noisy classes (air ends near -900) separates them equally
  // well; where exactly follows the tails.
  EXPECT_GT(otsu.threshold, -900);
  EXPECT_LT(otsu.threshold, -100);
  EXPECT_NEAR(otsu.lower_mean, -1000, 5);
  EXPECT_NEAR(otsu.upper_mean, 40, 5);
  EXPECT_GT(otsu.separability, 0.95);
  // The classes do not overlap: OpenCV takes the first of the equally good splits across the
  // gap, this one the middle (8-bit OpenCV sees the range in 255 steps).
  const double step = (otsu.bin_width * (kOtsuBins - 1)) / 255;
  EXPECT_GE(otsu.threshold, opencv_otsu(volume) - 2 * step);
  // The upper class is the ball: its share matches the voxels >= threshold.
  std::size_t above = 0;
  for (float v : volume.samples()) above += v >= otsu.threshold ? 1 : 0;
  EXPECT_NEAR(otsu.upper_fraction, double(above) / double(volume.samples().size()), 1e-9);
}

TEST(OtsuThreshold, MrLikeVolumeInItsOwnUnits) {
  // Background near 0 (positive, as MR magnitude images are), tissue around 600.
  auto volume = ball_volume(0, 600, 40, 2);
  for (float& v : volume.samples()) v = std::abs(v);
  const OtsuThreshold otsu = otsu_threshold(volume);
  EXPECT_GT(otsu.threshold, 100);
  EXPECT_LT(otsu.threshold, 500);
  const double step = (otsu.bin_width * (kOtsuBins - 1)) / 255;
  EXPECT_GE(otsu.threshold, opencv_otsu(volume) - 2 * step);
}

TEST(OtsuThreshold, AgreesWithOpenCvWhenTheClassesOverlap) {
  // Noise as wide as the classes are apart: one best split, which 8-bit OpenCV finds to
  // within two of its steps.
  for (unsigned seed : {4u, 5u}) {
    const auto volume = ball_volume(-1000, 40, 300, seed);
    const OtsuThreshold otsu = otsu_threshold(volume);
    const double step = (otsu.bin_width * (kOtsuBins - 1)) / 255;
    EXPECT_NEAR(otsu.threshold, opencv_otsu(volume), 2 * step) << seed;
  }
}

TEST(OtsuThreshold, DoesNotDependOnTheUnits) {
  // An affine change of units moves the threshold with it.
  const auto volume = ball_volume(-1000, 40, 30, 3);
  auto scaled = volume;
  for (float& v : scaled.samples()) v = 2.0f * v + 3000.0f;
  const double a = otsu_threshold(volume).threshold, b = otsu_threshold(scaled).threshold;
  EXPECT_NEAR(b, 2 * a + 3000, 2 * 2 * otsu_threshold(volume).bin_width);
}

TEST(OtsuThreshold, RefusesAConstantVolume) {
  core::Volume volume({4, 4, 4}, spacing_geometry(1, 1, 1));
  for (float& v : volume.samples()) v = 7;
  EXPECT_THROW(otsu_threshold(volume), std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::preprocess
