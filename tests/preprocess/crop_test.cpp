// Cropping: expected sizes and origins; every kept voxel keeps its patient position and value.
#include "preprocess/crop.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "preprocess_test_volumes.h"

namespace typemerge::preprocess {
namespace {

using core::Vec3;
using core::Volume;
using test::patient_field;
using test::spacing_geometry;

double field(const Vec3& p) { return p[0] + 100 * p[1] + 10000 * p[2]; }

void expect_near(const Vec3& a, const Vec3& b) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-9) << "component " << c;
}

// Cropped voxel (i, j, k) is input voxel offset + (i, j, k): same position, same value.
void expect_same_voxels(const Volume& input, const Volume& cropped, const IndexBox& box) {
  const auto& s = cropped.size();
  for (std::int64_t k = 0; k < s.nz; ++k) {
    for (std::int64_t j = 0; j < s.ny; ++j) {
      for (std::int64_t i = 0; i < s.nx; ++i) {
        const std::int64_t ii = i + box.begin[0], jj = j + box.begin[1], kk = k + box.begin[2];
        ASSERT_EQ(cropped.at(i, j, k), input.at(ii, jj, kk));
        const Vec3 p = cropped.geometry().apply(double(i), double(j), double(k));
        const Vec3 q = input.geometry().apply(double(ii), double(jj), double(kk));
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(p[c], q[c], 1e-9);
      }
    }
  }
}

const core::IndexToPatient kGeometry = spacing_geometry(0.5, 0.8, 2.0, {10, -20, 30});

TEST(Crop, IndexBoxGivesExpectedSizeAndOrigin) {
  const Volume volume = patient_field({20, 16, 10}, kGeometry, field);
  const IndexBox box{{2, 3, 4}, {12, 13, 9}};
  const StepResult result = crop(volume, box);
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{10, 10, 5}));
  expect_near(result.volume.geometry().origin, {11, -17.6, 38});
  EXPECT_EQ(result.volume.geometry().axes, kGeometry.axes);
  expect_same_voxels(volume, result.volume, box);
  EXPECT_TRUE(result.record.warnings.empty());
  EXPECT_EQ(*result.record.parameter("begin_k"), "4");
}

TEST(Crop, KeepsPatientPositionsOnAShearedGrid) {
  core::IndexToPatient geometry;
  geometry.origin = {-3, 7, 40};
  geometry.axes = {{{0.6, 0.1, 0}, {-0.1, 0.6, 0}, {0, 0.5, 2.45}}};
  const Volume volume = patient_field({12, 11, 9}, geometry, field);
  const IndexBox box{{1, 2, 3}, {10, 8, 7}};
  expect_same_voxels(volume, crop(volume, box).volume, box);
}

TEST(Crop, ClampsABoxPartlyOutsideAndWarns) {
  const Volume volume = patient_field({20, 16, 10}, kGeometry, field);
  const StepResult result = crop(volume, {{-5, 0, 8}, {5, 100, 12}});
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{5, 16, 2}));
  EXPECT_EQ(result.record.warnings.size(), 1u);
  expect_same_voxels(volume, result.volume, {{0, 0, 8}, {5, 16, 10}});
}

TEST(Crop, RejectsABoxOutsideTheVolume) {
  const Volume volume({20, 16, 10}, kGeometry);
  EXPECT_THROW(crop(volume, {{20, 0, 0}, {25, 5, 5}}), std::invalid_argument);
  EXPECT_THROW(crop(volume, {{4, 4, 4}, {4, 8, 8}}), std::invalid_argument);
}

// Voxel centres x = 10 + 0.5 i, y = −20 + 0.8 j, z = 30 + 2 k inside the box (faces included).
TEST(CropToPatientBox, GivesTheVoxelsWhoseCentresLieInTheBox) {
  const Volume volume = patient_field({20, 16, 10}, kGeometry, field);
  const PatientBox box{{11, -18, 34}, {14, -14, 40}};
  EXPECT_EQ(index_box_of(volume, box), (IndexBox{{2, 3, 2}, {9, 8, 6}}));
  const StepResult result = crop_to_patient_box(volume, box);
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{7, 5, 4}));
  expect_near(result.volume.geometry().origin, {11, -17.6, 34});
  expect_same_voxels(volume, result.volume, {{2, 3, 2}, {9, 8, 6}});
}

TEST(CropToPatientBox, InvertsARotatedGeometry) {
  // Index axes i → −x (mirrored) and j → +y: i = (origin_x − x)/0.5.
  core::IndexToPatient geometry;
  geometry.origin = {0, 0, 0};
  geometry.axes = {{{-0.5, 0, 0}, {0, 1, 0}, {0, 0, 2}}};
  const Volume volume({40, 10, 10}, geometry);
  EXPECT_EQ(index_box_of(volume, {{-5, 2, 4}, {-2, 3.5, 4}}), (IndexBox{{4, 2, 2}, {11, 4, 3}}));
}

TEST(CropToPatientBox, RejectsInvalidOrMissingBoxes) {
  const Volume volume({20, 16, 10}, kGeometry);
  EXPECT_THROW(crop_to_patient_box(volume, {{5, 0, 0}, {4, 1, 1}}), std::invalid_argument);
  EXPECT_THROW(crop_to_patient_box(volume, {{-100, -100, -100}, {-90, -90, -90}}),
               std::invalid_argument);
}

Volume air_with_block(const core::IndexToPatient& geometry) {
  Volume volume({30, 20, 12}, geometry);
  for (float& v : volume.samples()) v = -1000;
  for (std::int64_t k = 3; k < 5; ++k) {
    for (std::int64_t j = 4; j < 7; ++j) {
      for (std::int64_t i = 5; i < 9; ++i) volume.at(i, j, k) = 40;
    }
  }
  volume.at(29, 19, 11) = -600;  // below the threshold: not tissue
  return volume;
}

TEST(CropToTissue, FindsTheBoundingBoxWithTheMargin) {
  const auto geometry = spacing_geometry(0.5, 1.0, 2.0, {1, 2, 3});
  const Volume volume = air_with_block(geometry);
  EXPECT_EQ(tissue_bounding_box(volume, -400), (IndexBox{{5, 4, 3}, {9, 7, 5}}));
  // 1.5 mm margin: 3, 2 and 1 voxels along i, j, k.
  const StepResult result = crop_to_tissue(volume, {.threshold_hu = -400, .margin_mm = 1.5});
  EXPECT_EQ(result.volume.size(), (core::VolumeSize{10, 7, 4}));
  expect_near(result.volume.geometry().origin, geometry.apply(2, 2, 2));
  expect_same_voxels(volume, result.volume, {{2, 2, 2}, {12, 9, 6}});
  EXPECT_EQ(*result.record.parameter("tissue_found"), "true");
  EXPECT_TRUE(result.record.warnings.empty());
}

TEST(CropToTissue, ClampsTheMarginAtTheVolumeFaces) {
  const Volume volume = air_with_block(spacing_geometry(1, 1, 1));
  const StepResult result = crop_to_tissue(volume, {.threshold_hu = -400, .margin_mm = 100});
  EXPECT_EQ(result.volume.size(), volume.size());
  EXPECT_EQ(result.volume.geometry().origin, volume.geometry().origin);
}

TEST(CropToTissue, LeavesAVolumeWithoutTissueUncroppedWithAWarning) {
  Volume volume({8, 8, 4}, spacing_geometry(1, 1, 1));
  for (float& v : volume.samples()) v = -1000;
  EXPECT_TRUE(tissue_bounding_box(volume, -400).empty());
  const StepResult result = crop_to_tissue(volume, {});
  EXPECT_EQ(result.volume.size(), volume.size());
  EXPECT_EQ(*result.record.parameter("tissue_found"), "false");
  ASSERT_EQ(result.record.warnings.size(), 1u);
  EXPECT_NE(result.record.warnings[0].find("no voxel"), std::string::npos);
}

TEST(CropToTissue, RejectsANegativeMargin) {
  const Volume volume({8, 8, 4}, spacing_geometry(1, 1, 1));
  EXPECT_THROW(crop_to_tissue(volume, {.threshold_hu = 0, .margin_mm = -1}), std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::preprocess
