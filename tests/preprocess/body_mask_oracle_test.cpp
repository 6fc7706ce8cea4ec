// Table removal on run-length masks against its byte-mask oracle (OpenCV's morphology): the
// run operations against cv::erode / cv::dilate on random slices, then remove_outside_body
// against the oracle voxel by voxel, record by record, on a synthetic body lying on a table
// and on every real series (issue 15, item 2).
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "body_mask_oracle.h"
#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "preprocess/body_mask.h"
#include "preprocess/run_mask.h"
#include "preprocess_test_volumes.h"
#include "support/test_data.h"

namespace typemerge::preprocess {
namespace {

cv::Mat to_mat(const runs::SliceRuns& slice) {
  cv::Mat out = cv::Mat::zeros(slice.rows(), slice.cols, CV_8U);
  for (std::int32_t y = 0; y < slice.rows(); ++y) {
    for (const runs::Run* r = slice.row_begin(y); r != slice.row_end(y); ++r) {
      for (std::int32_t x = r->begin; x < r->end; ++x) out.at<std::uint8_t>(y, x) = 255;
    }
  }
  return out;
}

// Blobs of random size, some touching the image's edges, and speckle.
std::vector<float> random_slice(int cols, int rows, std::mt19937& rng) {
  std::vector<float> values(static_cast<std::size_t>(cols * rows), -1000.0f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int blob = 0; blob < 6; ++blob) {
    const double cx = u(rng) * cols, cy = u(rng) * rows;
    const double ax = 1 + u(rng) * cols / 3.0, ay = 1 + u(rng) * rows / 3.0;
    for (int y = 0; y < rows; ++y) {
      for (int x = 0; x < cols; ++x) {
        const double dx = (x - cx) / ax, dy = (y - cy) / ay;
        if (dx * dx + dy * dy <= 1) values[static_cast<std::size_t>(y * cols + x)] = 40.0f;
      }
    }
  }
  for (float& v : values) {
    if (u(rng) < 0.03) v = v > 0 ? -1000.0f : 40.0f;
  }
  return values;
}

// The int16 route (whole blocks of 16 compared at once) against the definition, pixel by
// pixel in float: rows of every length around the block size, runs starting and ending at every
// position in a block, and thresholds between, on and beyond the samples, the int16 limits and
// NaN included.
TEST(RunMask, Int16ThresholdEqualsTheFloatComparison) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> value(-32768, 32767);
  std::uniform_int_distribution<int> run_length(1, 40);
  const float thresholds[] = {-200.0f, -200.5f, -199.5f, 0.0f, 40.0f, 32766.5f, 32767.0f,
                              -32768.0f, -32768.5f, -INFINITY, INFINITY, NAN};
  for (int trial = 0; trial < 60; ++trial) {
    SCOPED_TRACE(trial);
    const int cols = 1 + trial % 37, rows = 1 + trial % 5;
    std::vector<std::int16_t> samples(static_cast<std::size_t>(cols * rows));
    // Runs of one value each (below, at or above -200, or anywhere in int16).
    for (std::size_t p = 0; p < samples.size();) {
      const int kind = value(rng) & 3;
      const auto v = static_cast<std::int16_t>(kind == 0   ? -1000
                                               : kind == 1 ? -200
                                               : kind == 2 ? 40
                                                           : value(rng));
      for (int n = run_length(rng); n > 0 && p < samples.size(); --n) samples[p++] = v;
    }
    for (const float t : thresholds) {
      SCOPED_TRACE(t);
      const runs::SliceRuns got = runs::threshold_above(samples.data(), cols, rows, t);
      ASSERT_EQ(got.cols, cols);
      ASSERT_EQ(got.rows(), rows);
      std::vector<std::uint8_t> set(samples.size(), 0);
      for (std::int32_t y = 0; y < rows; ++y) {
        for (const runs::Run* r = got.row_begin(y); r != got.row_end(y); ++r) {
          ASSERT_LT(r->begin, r->end);
          if (r != got.row_begin(y)) {
            ASSERT_LT((r - 1)->end, r->begin);  // not touching
          }
          for (std::int32_t x = r->begin; x < r->end; ++x) set[y * cols + x] = 1;
        }
      }
      for (std::size_t p = 0; p < samples.size(); ++p) {
        ASSERT_EQ(set[p] == 1, static_cast<float>(samples[p]) > t) << "pixel " << p;
      }
    }
  }
}

TEST(RunMask, MorphologyEqualsOpenCvWithItsDefaultBorders) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    SCOPED_TRACE(trial);
    const int cols = 20 + trial % 7 * 9, rows = 15 + trial % 5 * 11;
    const std::vector<float> values = random_slice(cols, rows, rng);
    const runs::SliceRuns slice = runs::threshold_above(values.data(), cols, rows, -200.0f);
    cv::Mat bytes(rows, cols, CV_8U);
    for (int p = 0; p < cols * rows; ++p) bytes.data[p] = values[static_cast<std::size_t>(p)] > -200 ? 255 : 0;
    ASSERT_EQ(cv::countNonZero(to_mat(slice) != bytes), 0);
    const int rx = 1 + trial % 6, ry = 1 + (trial / 6) % 5;  // anisotropic too
    const cv::Mat element =
        cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
    const runs::Kernel kernel = runs::ellipse_kernel(rx, ry);
    cv::Mat eroded, dilated, opened;
    cv::erode(bytes, eroded, element);
    cv::dilate(bytes, dilated, element);
    cv::morphologyEx(bytes, opened, cv::MORPH_OPEN, element);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::erode(slice, kernel)) != eroded), 0);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::dilate(slice, kernel)) != dilated), 0);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::dilate(runs::erode(slice, kernel), kernel)) != opened),
              0);
    const std::vector<float> other_values = random_slice(cols, rows, rng);
    const runs::SliceRuns other =
        runs::threshold_above(other_values.data(), cols, rows, -200.0f);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::unite(slice, other)) != cv::max(bytes, to_mat(other))), 0);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::intersect(slice, other)) != cv::min(bytes, to_mat(other))),
              0);
    EXPECT_EQ(cv::countNonZero(to_mat(runs::subtract(slice, other)) !=
                               (bytes & ~to_mat(other))),
              0);
    EXPECT_EQ(runs::intersect(slice, other).count(),
              static_cast<std::uint64_t>(cv::countNonZero(cv::min(bytes, to_mat(other)))));
  }
}

// Two cubes joined only through a diagonal (not 6-connected) and a larger one: the larger
// is kept; equal sizes: the one met first.
TEST(RunMask, LargestComponentIsSixConnected) {
  auto make = [](int n) {
    std::vector<runs::SliceRuns> slices;
    for (int k = 0; k < n; ++k) {
      std::vector<float> v(100, -1000.0f);
      if (k < 2) { v[0] = v[1] = 40; }                    // component A: 2 × 1 × 2
      if (k == 2) v[11 + 1] = 40;                          // diagonal from A: its own
      if (k >= 3) { for (int x = 5; x < 9; ++x) v[50 + x] = 40; }  // component C
      slices.push_back(runs::threshold_above(v.data(), 10, 10, 0.0f));
    }
    return slices;
  };
  std::vector<runs::SliceRuns> slices = make(4);  // A: 4 voxels, diagonal: 1, C: 4 (tie)
  EXPECT_EQ(runs::keep_largest_component(slices), 3u);
  EXPECT_EQ(slices[0].count(), 2u);  // A, met first
  EXPECT_EQ(slices[3].count(), 0u);
  std::vector<runs::SliceRuns> longer = make(5);  // C: 8 voxels
  EXPECT_EQ(runs::keep_largest_component(longer), 3u);
  EXPECT_EQ(longer[0].count(), 0u);
  EXPECT_EQ(longer[4].count(), 4u);
  std::vector<runs::SliceRuns> empty(3, runs::threshold_above(std::vector<float>(4, -1.0f).data(), 2, 2, 0.0f));
  EXPECT_EQ(runs::keep_largest_component(empty), 0u);
}

// Returns the number of voxels cleared.
std::int64_t expect_same_as_oracle(const core::Volume& volume, const BodyMaskOptions& options = {}) {
  // The oracle reads floats; the step reads the volume as loaded (int16 for most CT).
  core::Volume as_float = volume;
  as_float.to_float();
  const StepResult oracle = oracle::remove_outside_body_with_byte_masks(as_float, options);
  StepResult runs = remove_outside_body(volume, options);
  EXPECT_EQ(runs.volume.sample_type(), volume.sample_type());
  runs.volume.to_float();
  EXPECT_EQ(runs.record.description, oracle.record.description);
  EXPECT_EQ(runs.record.parameters, oracle.record.parameters);
  EXPECT_EQ(runs.record.warnings, oracle.record.warnings);
  std::size_t differ = 0;
  for (std::size_t p = 0; p < as_float.samples().size(); ++p) {
    differ += runs.volume.samples()[p] != oracle.volume.samples()[p];
  }
  EXPECT_EQ(differ, 0u) << "voxels that differ from the oracle";
  for (const auto& [key, value] : runs.record.parameters) {
    if (key == "cleared_voxels") return std::stoll(value);
  }
  return -1;
}

TEST(BodyMaskOracle, SyntheticBodyOnATableIsClearedAsByTheOracle) {
  // The table, rails, pad and arm rest: thousands of voxels per slice.
  EXPECT_GT(expect_same_as_oracle(test::body_lying_on_a_table(256, 12)), 12 * 2000);
  BodyMaskOptions options;
  options.edge_mm = 0;
  options.opening_mm = 3.3;
  options.restore_mm = 0;
  EXPECT_GT(expect_same_as_oracle(test::body_lying_on_a_table(256, 5), options), 5 * 2000);
}

TEST(BodyMaskOracle, RealSeriesAreClearedAsByTheOracle) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  for (const char* name : {"abdomen", "phantom_study", "head_tilt_variable", "head64_resampled"}) {
    SCOPED_TRACE(name);
    dicom::ScanOptions scan_options;
    scan_options.geometry.spacing = dicom::SpacingPolicy::resample;
    const dicom::FolderScan scan = dicom::scan_folder(data / "ct" / name, scan_options);
    ASSERT_TRUE(scan.default_series.has_value());
    const std::int64_t cleared =
        expect_same_as_oracle(dicom::load_series(scan.series[*scan.default_series]).volume);
    // The abdomen lies on a table; the phantom and the heads' holders are left alone or cut.
    if (std::string(name) == "abdomen") {
      EXPECT_GT(cleared, 1000000);
    }
  }
}

}  // namespace
}  // namespace typemerge::preprocess
