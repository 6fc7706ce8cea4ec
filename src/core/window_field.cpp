#include "core/window_field.h"

#include <algorithm>
#include <cassert>

namespace typemerge::core {

Volume window_field(const Volume& volume, float lo, float hi) {
  assert(lo <= hi);
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
