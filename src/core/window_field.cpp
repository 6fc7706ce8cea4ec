#include "core/window_field.h"

#include <algorithm>
#include <cassert>

namespace typemerge::core {

Volume window_field(const Volume& volume, float lo, float hi) {
  assert(lo <= hi);
  Volume field(volume.size(), volume.geometry());
  const Samples& in = volume.samples();
  Samples& out = field.samples();
  for (std::size_t v = 0; v < in.size(); ++v) out[v] = std::min(in[v] - lo, hi - in[v]);
  return field;
}

std::int64_t count_in_window(const Volume& volume, float lo, float hi) {
  return std::count_if(volume.samples().begin(), volume.samples().end(),
                       [&](float v) { return v >= lo && v <= hi; });
}

}  // namespace typemerge::core
