#include "core/window_field.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>

namespace typemerge::core {

namespace {

// The field in int16 when it is whole numbers that fit: int16 samples and whole bounds, and no
// sample farther than int16's range from both (none on CT). Else an empty volume.
Volume window_field_int16(const Volume& volume, float lo, float hi) {
  constexpr float kBound = 65536.0f;  // bounds beyond any int16 sample ± int16's range
  if (!volume.holds_int16() || lo != std::floor(lo) || hi != std::floor(hi) ||
      !(std::abs(lo) < kBound) || !(std::abs(hi) < kBound)) {
    return {};
  }
  Volume field = Volume::uninitialized(volume.size(), volume.geometry(), SampleType::int16);
  const auto low = static_cast<std::int32_t>(lo);
  const auto high = static_cast<std::int32_t>(hi);
  const std::int16_t* in = volume.int16_samples().data();
  std::int16_t* out = field.int16_samples().data();
  const std::size_t n = field.int16_samples().size();
  std::int32_t least = 0;
  std::int32_t most = 0;
  for (std::size_t v = 0; v < n; ++v) {
    const std::int32_t f = std::min(in[v] - low, high - in[v]);
    least = std::min(least, f);
    most = std::max(most, f);
    out[v] = static_cast<std::int16_t>(f);  // kept only if every one fits
  }
  if (least < std::numeric_limits<std::int16_t>::min() ||
      most > std::numeric_limits<std::int16_t>::max()) {
    return {};
  }
  return field;
}

}  // namespace

Volume window_field(const Volume& volume, float lo, float hi) {
  assert(lo <= hi);
  if (Volume field = window_field_int16(volume, lo, hi); field.size().voxels() > 0) return field;
  // Every sample is written below, so the field's pages are not zeroed first.
  Volume field = Volume::uninitialized(volume.size(), volume.geometry());
  Samples& out = field.samples();
  volume.visit([&](const auto* in) {
    for (std::size_t v = 0; v < out.size(); ++v) {
      const float value = in[v];
      out[v] = std::min(value - lo, hi - value);
    }
  });
  return field;
}

WindowCover window_cover(const Volume& volume, float lo, float hi) {
  return volume.visit([&](const auto* samples) {
    bool inside = false, outside = false;
    const auto n = static_cast<std::size_t>(volume.size().voxels());
    for (std::size_t i = 0; i < n; ++i) {
      const float v = samples[i];
      (v >= lo && v <= hi ? inside : outside) = true;
      if (inside && outside) return WindowCover::some;
    }
    return inside ? WindowCover::all : WindowCover::none;
  });
}

}  // namespace typemerge::core
