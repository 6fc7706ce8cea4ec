// CIELab → sRGB against reference values computed independently (CIE 15 and IEC 61966-2-1,
// the same D65 white as DICOM), and DICOM's 16-bit scaling.
#include <gtest/gtest.h>

#include <cmath>

#include "seg/cielab.h"

namespace typemerge::seg {
namespace {

void expect_rgb(const std::array<std::uint8_t, 3>& rgb, int r, int g, int b, int slack = 1) {
  EXPECT_NEAR(rgb[0], r, slack);
  EXPECT_NEAR(rgb[1], g, slack);
  EXPECT_NEAR(rgb[2], b, slack);
}

// DICOM's scaling: L* 0..100 → 0..65535, a*/b* -128..127 → 0..65535.
std::uint16_t scale_l(double l) { return static_cast<std::uint16_t>(std::lround(l * 65535.0 / 100.0)); }
std::uint16_t scale_ab(double v) {
  return static_cast<std::uint16_t>(std::lround((v + 128.0) * 65535.0 / 255.0));
}

TEST(CieLab, DicomScalingEnds) {
  const CieLab lab = cielab_from_dicom(65535, 0, 65535);
  EXPECT_DOUBLE_EQ(lab.l, 100.0);
  EXPECT_DOUBLE_EQ(lab.a, -128.0);
  EXPECT_DOUBLE_EQ(lab.b, 127.0);
}

TEST(CieLab, WhiteBlackAndGrey) {
  expect_rgb(srgb_from_cielab({100, 0, 0}), 255, 255, 255);
  expect_rgb(srgb_from_cielab({0, 0, 0}), 0, 0, 0, 0);
  // L* 53.585 is sRGB 128 grey (Y = 0.2158).
  expect_rgb(srgb_from_cielab({53.585, 0, 0}), 128, 128, 128);
}

TEST(CieLab, PrimariesFromTheirPublishedLab) {
  // sRGB primaries and secondaries in CIELab (D65), as colour-science references list them.
  expect_rgb(srgb_from_cielab({53.2408, 80.0925, 67.2032}), 255, 0, 0);
  expect_rgb(srgb_from_cielab({87.7347, -86.1827, 83.1793}), 0, 255, 0);
  expect_rgb(srgb_from_cielab({32.2970, 79.1875, -107.8602}), 0, 0, 255);
  expect_rgb(srgb_from_cielab({97.1393, -21.5537, 94.4780}), 255, 255, 0);
}

TEST(CieLab, ThroughDicomScaling) {
  expect_rgb(srgb_from_dicom_cielab(scale_l(53.2408), scale_ab(80.0925), scale_ab(67.2032)), 255,
             0, 0);
  // 3D Slicer's liver colour (221, 130, 101) as dcmqi writes it in the shared liver SEGs.
  expect_rgb(srgb_from_dicom_cielab(41661, 41167, 40792), 221, 130, 101);
}

TEST(CieLab, OutOfGamutIsClipped) {
  const auto rgb = srgb_from_cielab({50, 127, -128});
  EXPECT_LE(rgb[1], 10);  // a deep magenta: no green
  EXPECT_EQ(srgb_from_cielab({100, 0, 127})[0], 255);
}

}  // namespace
}  // namespace typemerge::seg
