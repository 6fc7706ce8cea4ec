// window_field: turns "voxels whose value lies in [lo, hi]" into an isosurface problem.
//
// f = min(v − lo, hi − v) is ≥ 0 exactly inside the window and, along a cube edge that crosses
// only one bound, linear in v, so marching cubes at iso 0 on f places vertices where the
// original data crosses lo or hi — the same positions as extracting v = lo or v = hi. When
// `hi` is at or above the data's maximum the result equals extracting v ≥ lo directly.
// Storage: int16 when the samples are int16, lo and hi whole numbers and every value of f fits
// int16 (all CT: it needs a sample more than 32,767 from both bounds), else float. The values
// are the same either way (f is a whole number then), and extractors read an int16 sample as
// the float of the same integer (volume.h), so the surfaces are too. Memory: one more volume
// of that storage (the caller may drop the original afterwards).
#pragma once

#include "core/volume.h"

namespace typemerge::core {

// Precondition: lo <= hi.
Volume window_field(const Volume& volume, float lo, float hi);

// Whether [lo, hi] holds none, some or all of the samples, for "is this tissue there at all"
// checks: a surface needs some inside and some outside. Answered as soon as one of each is
// seen (usually within the first slice), not by reading the whole volume.
enum class WindowCover { none, some, all };
WindowCover window_cover(const Volume& volume, float lo, float hi);

}  // namespace typemerge::core
