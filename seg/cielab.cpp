#include "seg/cielab.h"

#include <algorithm>
#include <cmath>

namespace typemerge::seg {
namespace {

// D65 reference white, Y = 1 (CIE 15, 2-degree observer), as sRGB defines it.
constexpr double kWhiteX = 0.95047;
constexpr double kWhiteY = 1.0;
constexpr double kWhiteZ = 1.08883;

// CIE's inverse of f(t): t³ above (6/29)³, its linear part below.
double lab_f_inverse(double t) {
  constexpr double kDelta = 6.0 / 29.0;
  return t > kDelta ? t * t * t : 3.0 * kDelta * kDelta * (t - 4.0 / 29.0);
}

// Linear light → the sRGB transfer curve, 8 bits.
std::uint8_t encode_srgb(double linear) {
  linear = std::clamp(linear, 0.0, 1.0);
  const double encoded =
      linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
  return static_cast<std::uint8_t>(std::lround(std::clamp(encoded, 0.0, 1.0) * 255.0));
}

}  // namespace

CieLab cielab_from_dicom(std::uint16_t l, std::uint16_t a, std::uint16_t b) {
  return {l * 100.0 / 65535.0, a * 255.0 / 65535.0 - 128.0, b * 255.0 / 65535.0 - 128.0};
}

std::array<std::uint8_t, 3> srgb_from_cielab(const CieLab& lab) {
  const double fy = (lab.l + 16.0) / 116.0;
  const double fx = fy + lab.a / 500.0;
  const double fz = fy - lab.b / 200.0;
  const double x = kWhiteX * lab_f_inverse(fx);
  const double y = kWhiteY * lab_f_inverse(fy);
  const double z = kWhiteZ * lab_f_inverse(fz);
  // IEC 61966-2-1 XYZ → linear sRGB.
  const double r = 3.2404542 * x - 1.5371385 * y - 0.4985314 * z;
  const double g = -0.9692660 * x + 1.8760108 * y + 0.0415560 * z;
  const double bl = 0.0556434 * x - 0.2040259 * y + 1.0572252 * z;
  return {encode_srgb(r), encode_srgb(g), encode_srgb(bl)};
}

}  // namespace typemerge::seg
