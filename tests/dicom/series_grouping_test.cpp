#include <gtest/gtest.h>

#include "dicom/series_scan.h"

namespace typemerge::dicom {
namespace {

SliceHeader slice(const std::string& series_uid, double z, int index) {
  SliceHeader s;
  s.path = series_uid + "_" + std::to_string(index);
  s.kind = FileKind::ct_image;
  s.study_uid = "1.2.study";
  s.series_uid = series_uid;
  s.frame_of_reference_uid = "1.2.for";
  s.sop_instance_uid = s.path.string();
  s.image_type = "ORIGINAL\\PRIMARY\\AXIAL";
  s.modality = "CT";
  s.rows = 8;
  s.columns = 8;
  s.position = Vec3{0, 0, z};
  s.orientation = std::array<double, 6>{1, 0, 0, 0, 1, 0};
  s.pixel_spacing = std::array<double, 2>{1, 1};
  return s;
}

TEST(SeriesGrouping, SeparatesSeriesAndChoosesTheLargest) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 5; ++k) headers.push_back(slice("1.2.a", k * 2.0, k));
  for (int k = 0; k < 9; ++k) headers.push_back(slice("1.2.b", k * 1.0, k));
  const auto series = group_into_series(headers, {});
  ASSERT_EQ(series.size(), 2u);
  const auto chosen = choose_default_series(series);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(series[*chosen].slices.size(), 9u);
  EXPECT_NE(series[0].id, series[1].id);
}

TEST(SeriesGrouping, TieGoesToThinnerSpacing) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 5; ++k) headers.push_back(slice("1.2.thick", k * 3.0, k));
  for (int k = 0; k < 5; ++k) headers.push_back(slice("1.2.thin", k * 1.0, k));
  const auto series = group_into_series(headers, {});
  const auto chosen = choose_default_series(series);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_NEAR(series[*chosen].geometry.slice_step_mm, 1.0, 1e-12);
}

TEST(SeriesGrouping, LocalizerByImageTypeIsNeverAVolume) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 3; ++k) {
    auto s = slice("1.2.scout", k * 1.0, k);
    s.image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
    headers.push_back(s);
  }
  const auto series = group_into_series(headers, {});
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(series[0].role, SeriesRole::localizer);
  EXPECT_FALSE(choose_default_series(series).has_value());
}

TEST(SeriesGrouping, OrientationOutlierInsideASeriesIsSplitOff) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 6; ++k) headers.push_back(slice("1.2.mixed", k * 1.0, k));
  auto scout = slice("1.2.mixed", 0.0, 99);
  scout.orientation = std::array<double, 6>{1, 0, 0, 0, 0, -1};  // coronal
  headers.push_back(scout);
  const auto series = group_into_series(headers, {});
  ASSERT_EQ(series.size(), 2u);
  const auto chosen = choose_default_series(series);
  ASSERT_TRUE(chosen.has_value());
  EXPECT_EQ(series[*chosen].slices.size(), 6u);
  EXPECT_TRUE(series[*chosen].geometry.ok());
  const auto& other = series[1 - *chosen];
  EXPECT_EQ(other.role, SeriesRole::localizer);
  EXPECT_NE(other.role_reason.find("orientation"), std::string::npos);
}

TEST(SeriesGrouping, VendorImageTypeValuesDoNotSplitASeries) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 4; ++k) {
    auto s = slice("1.2.ge", k * 1.0, k);
    if (k % 2) s.image_type += "\\ADD";
    headers.push_back(s);
  }
  EXPECT_EQ(group_into_series(headers, {}).size(), 1u);
}

TEST(SeriesGrouping, IdsAreStableAcrossInputOrder) {
  std::vector<SliceHeader> headers;
  for (int k = 0; k < 4; ++k) headers.push_back(slice("1.2.x", k * 1.0, k));
  const auto forward = group_into_series(headers, {});
  std::reverse(headers.begin(), headers.end());
  const auto backward = group_into_series(headers, {});
  EXPECT_EQ(forward[0].id, backward[0].id);
  EXPECT_EQ(forward[0].slices.front().path, backward[0].slices.front().path);
}

}  // namespace
}  // namespace typemerge::dicom
