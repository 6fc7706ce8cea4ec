// otsu_threshold: the iso value that best separates a volume's voxels into two classes (Otsu
// 1979, "A threshold selection method from gray-level histograms"), for `convert --iso auto`.
//
// Over all voxels of a CT the two classes are air (and what the table removal cleared) and
// everything denser, so the threshold lands between air and soft tissue and its iso-surface
// is a skin-like surface. Nothing in it assumes Hounsfield units: on an MR volume it separates
// background from signal the same way, in the volume's own units.
//
// The histogram: kOtsuBins bins of equal width from the smallest to the largest value, counted
// slice by slice with OpenCV's calcHist (exact: each slice has fewer than 2^24 voxels, the
// float counts of one call are integers) and summed in 64 bits. The threshold returned is the
// lower edge of the first bin of the upper class, so the voxels `>= threshold` are exactly the
// upper class (up to values that sit on a bin edge in float). Cost: one pass over the voxels;
// memory: the histogram.
#pragma once

#include <cstdint>
#include <vector>

#include "core/volume.h"

namespace typemerge::preprocess {

inline constexpr int kOtsuBins = 4096;

struct OtsuThreshold {
  double threshold = 0;   // in the volume's units (HU for CT); value >= threshold: upper class
  double lower_mean = 0;  // mean of each class, volume units
  double upper_mean = 0;
  double upper_fraction = 0;  // share of the voxels in the upper class
  double separability = 0;    // between-class / total variance, in [0, 1] (Otsu's η)
  double bin_width = 0;       // histogram resolution, volume units
};

// Throws std::invalid_argument when the volume is empty, holds a non-finite value or is
// constant (there is nothing to separate).
OtsuThreshold otsu_threshold(const core::Volume& volume);

namespace detail {
// Otsu's rule on a histogram: the number of bins k (1 <= k < size) in the lower class that
// maximises the between-class variance; when a run of k ties (empty bins between the classes),
// the middle of the first such run, rounded up. Precondition: at least two non-empty bins.
int otsu_split(const std::vector<std::uint64_t>& histogram);
}  // namespace detail

}  // namespace typemerge::preprocess
