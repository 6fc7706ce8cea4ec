#include "core/window_field.h"

#include <algorithm>
#include <cassert>

namespace typemerge::core {

Volume window_field(const Volume& volume, float lo, float hi) {
  assert(lo <= hi);
  // Every sample is written below, so the field's pages are not zeroed first.
  Volume field = Volume::uninitialized(volume.size(), volume.geometry());
  const Samples& in = volume.samples();
  Samples& out = field.samples();
  for (std::size_t v = 0; v < in.size(); ++v) out[v] = std::min(in[v] - lo, hi - in[v]);
  return field;
}

WindowCover window_cover(const Volume& volume, float lo, float hi) {
  bool inside = false, outside = false;
  for (const float v : volume.samples()) {
    (v >= lo && v <= hi ? inside : outside) = true;
    if (inside && outside) return WindowCover::some;
  }
  return inside ? WindowCover::all : WindowCover::none;
}

}  // namespace typemerge::core
