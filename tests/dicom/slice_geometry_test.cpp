#include "dicom/slice_geometry.h"

#include <gtest/gtest.h>

#include <cmath>

namespace typemerge::dicom {
namespace {

// An axial slice of a made-up series at table position z (mm), with an optional shear.
SliceHeader axial_slice(double z, const std::string& name, double shear_y_per_mm = 0.0) {
  SliceHeader slice;
  slice.path = name;
  slice.sop_instance_uid = "1.2.3." + name;
  slice.rows = 4;
  slice.columns = 5;
  slice.position = Vec3{-10.0, -20.0 + shear_y_per_mm * z, z};
  slice.orientation = std::array<double, 6>{1, 0, 0, 0, 1, 0};
  slice.pixel_spacing = std::array<double, 2>{0.5, 0.25};
  return slice;
}

std::vector<SliceHeader> stack(const std::vector<double>& zs) {
  std::vector<SliceHeader> slices;
  for (std::size_t k = 0; k < zs.size(); ++k) {
    slices.push_back(axial_slice(zs[k], "f" + std::to_string(k)));
  }
  return slices;
}

TEST(SliceGeometry, SortsAlongTheNormalNotByName) {
  const auto geometry = compute_stack_geometry(stack({9, 3, 0, 6}), {});
  ASSERT_TRUE(geometry.ok()) << geometry.error;
  EXPECT_EQ(geometry.order, (std::vector<std::size_t>{2, 1, 3, 0}));
  EXPECT_EQ(geometry.output_slices, 4);
  EXPECT_NEAR(geometry.slice_step_mm, 3.0, 1e-12);
  // Columns advance along the row direction by the column spacing (PixelSpacing[1]).
  const auto& map = geometry.index_to_patient;
  EXPECT_EQ(map.origin, (core::Vec3{-10, -20, 0}));
  EXPECT_EQ(map.axes[0], (core::Vec3{0.25, 0, 0}));
  EXPECT_EQ(map.axes[1], (core::Vec3{0, 0.5, 0}));
  EXPECT_EQ(map.axes[2], (core::Vec3{0, 0, 3}));
  EXPECT_DOUBLE_EQ(geometry.tilt_degrees, 0.0);
}

TEST(SliceGeometry, NormalPointingAgainstTableStillSorts) {
  // Row (1,0,0) and column (0,-1,0): the normal is −z, so offsets grow towards the feet.
  auto slices = stack({0, 2, 4});
  for (auto& s : slices) s.orientation = std::array<double, 6>{1, 0, 0, 0, -1, 0};
  const auto geometry = compute_stack_geometry(slices, {});
  ASSERT_TRUE(geometry.ok());
  EXPECT_EQ(geometry.order, (std::vector<std::size_t>{2, 1, 0}));
  EXPECT_NEAR(geometry.index_to_patient.axes[2][2], -2.0, 1e-12);
  EXPECT_GT(geometry.index_to_patient.determinant(), 0.0);
}

TEST(SliceGeometry, DropsDuplicateInstancesWithWarning) {
  auto slices = stack({0, 1, 2});
  slices.push_back(slices[1]);
  slices.back().path = "copy_of_f1";
  const auto geometry = compute_stack_geometry(slices, {});
  ASSERT_TRUE(geometry.ok()) << geometry.error;
  EXPECT_EQ(geometry.order.size(), 3u);
  ASSERT_EQ(geometry.dropped.size(), 1u);
  EXPECT_FALSE(geometry.warnings.empty());
}

TEST(SliceGeometry, TwoDifferentImagesAtOnePositionIsAnError) {
  auto slices = stack({0, 1, 2});
  slices.push_back(axial_slice(1, "other"));
  const auto geometry = compute_stack_geometry(slices, {});
  EXPECT_FALSE(geometry.ok());
  EXPECT_NE(geometry.error.find("same position"), std::string::npos) << geometry.error;
}

TEST(SliceGeometry, MissingSliceIsRefusedByDefault) {
  const auto geometry = compute_stack_geometry(stack({0, 2, 4, 8, 10}), {});
  EXPECT_FALSE(geometry.ok());
  EXPECT_NE(geometry.error.find("1 missing slice"), std::string::npos) << geometry.error;
}

TEST(SliceGeometry, UnevenSpacingResamplesOnRequest) {
  GeometryOptions options;
  options.spacing = SpacingPolicy::resample;
  const auto geometry = compute_stack_geometry(stack({0, 2, 4, 5, 8}), options);
  ASSERT_TRUE(geometry.ok()) << geometry.error;
  EXPECT_TRUE(geometry.needs_resampling);
  EXPECT_NEAR(geometry.slice_step_mm, 1.0, 1e-12);
  EXPECT_EQ(geometry.output_slices, 9);
  EXPECT_FALSE(geometry.warnings.empty());
}

TEST(SliceGeometry, GantryTiltIsMeasuredAndKeptAsShear) {
  // Positions advance along z while the slice plane stays axial-tilted: a sheared grid.
  const double tilt = 18.5 * M_PI / 180;
  std::vector<SliceHeader> slices;
  for (int k = 0; k < 5; ++k) {
    SliceHeader s = axial_slice(4.0 * k, "t" + std::to_string(k));
    s.orientation = std::array<double, 6>{1, 0, 0, 0, std::cos(tilt), -std::sin(tilt)};
    slices.push_back(s);
  }
  const auto geometry = compute_stack_geometry(slices, {});
  ASSERT_TRUE(geometry.ok()) << geometry.error;
  EXPECT_NEAR(geometry.tilt_degrees, 18.5, 1e-9);
  EXPECT_NEAR(geometry.index_to_patient.axes[2][2], 4.0, 1e-12);  // the step is the table step
  EXPECT_NEAR(geometry.slice_step_mm, 4.0 * std::cos(tilt), 1e-12);
  EXPECT_FALSE(geometry.warnings.empty());
}

TEST(SliceGeometry, PositionsOffALineAreRefused) {
  auto slices = stack({0, 1, 2, 3});
  (*slices[2].position)[0] += 3.0;  // one slice shifted sideways by 3 mm
  const auto geometry = compute_stack_geometry(slices, {});
  EXPECT_FALSE(geometry.ok());
  EXPECT_NE(geometry.error.find("line"), std::string::npos) << geometry.error;
}

TEST(SliceGeometry, SingleSliceIsNotAVolume) {
  EXPECT_FALSE(compute_stack_geometry(stack({0}), {}).ok());
}

TEST(SliceGeometry, NonOrthogonalOrientationIsRefused) {
  auto slices = stack({0, 1});
  for (auto& s : slices) s.orientation = std::array<double, 6>{1, 0, 0, 0.5, 0.866, 0};
  EXPECT_FALSE(compute_stack_geometry(slices, {}).ok());
}

}  // namespace
}  // namespace typemerge::dicom
