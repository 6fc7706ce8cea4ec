// DICOM's Recommended Display CIELab Value → an sRGB display colour.
//
// DICOM (PS3.3 C.10.7.1.1) stores CIELab as three 16-bit unsigned values scaled from
// L* in [0, 100] and a*, b* in [-128, 127] to [0, 65535], relative to the D65 white point.
// The conversion: unscale → CIE XYZ (D65, Y of white = 1) → linear sRGB (IEC 61966-2-1
// matrix) → sRGB transfer curve → 8 bits, rounded; colours outside the sRGB gamut are
// clipped per channel.
#pragma once

#include <array>
#include <cstdint>

namespace typemerge::seg {

struct CieLab {
  double l = 0;  // L*, 0..100
  double a = 0;  // a*, -128..127
  double b = 0;  // b*, -128..127
};

// The unscaled CIELab of DICOM's 16-bit triple.
CieLab cielab_from_dicom(std::uint16_t l, std::uint16_t a, std::uint16_t b);

// 8-bit sRGB, each channel rounded and clipped to [0, 255].
std::array<std::uint8_t, 3> srgb_from_cielab(const CieLab& lab);

inline std::array<std::uint8_t, 3> srgb_from_dicom_cielab(std::uint16_t l, std::uint16_t a,
                                                          std::uint16_t b) {
  return srgb_from_cielab(cielab_from_dicom(l, a, b));
}

}  // namespace typemerge::seg
