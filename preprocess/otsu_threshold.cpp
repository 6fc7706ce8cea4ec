#include "preprocess/otsu_threshold.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace typemerge::preprocess {

namespace detail {

int otsu_split(const std::vector<std::uint64_t>& histogram) {
  // Moments over the bins in double; bin b stands for the value b (the affine map to the
  // volume's units does not change which split wins).
  double total = 0, total_moment = 0;
  for (std::size_t b = 0; b < histogram.size(); ++b) {
    total += static_cast<double>(histogram[b]);
    total_moment += static_cast<double>(b) * static_cast<double>(histogram[b]);
  }
  assert(total > 0);
  const double mean = total_moment / total;
  double weight = 0, moment = 0, best = -1;
  // The best splits form a run when empty bins separate the classes (the variance does not
  // change across them): its middle is taken, halfway across the gap.
  std::size_t first = 1, last = 1;
  for (std::size_t k = 1; k < histogram.size(); ++k) {
    weight += static_cast<double>(histogram[k - 1]) / total;
    moment += static_cast<double>(k - 1) * static_cast<double>(histogram[k - 1]) / total;
    if (weight <= 0 || weight >= 1) continue;
    // σ_B²(k) = (μ_T ω − μ)² / (ω (1 − ω)), Otsu's eq. 18.
    const double between = (mean * weight - moment) * (mean * weight - moment) /
                           (weight * (1 - weight));
    if (between > best) {
      best = between;
      first = last = k;
    } else if (between == best && last == k - 1) {
      last = k;
    }
  }
  return static_cast<int>((first + last + 1) / 2);
}

}  // namespace detail

OtsuThreshold otsu_threshold(const core::Volume& volume) {
  const auto& size = volume.size();
  if (size.voxels() == 0) throw std::invalid_argument("Otsu threshold of an empty volume");
  const auto voxels = static_cast<std::size_t>(size.voxels());
  const auto [lo, hi] = volume.visit([&](const auto* samples) {
    const auto [low, high] = std::minmax_element(samples, samples + voxels);
    return std::pair<double, double>{static_cast<double>(*low), static_cast<double>(*high)};
  });
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    throw std::invalid_argument("Otsu threshold: the volume holds a non-finite value");
  }
  if (!(hi > lo)) {
    throw std::invalid_argument("Otsu threshold: every voxel has the same value, nothing to "
                                "separate");
  }
  // kOtsuBins − 1 widths span [lo, hi], so hi falls inside the last bin (calcHist's ranges
  // exclude their upper end).
  const double width = (hi - lo) / (kOtsuBins - 1);
  const float range[] = {static_cast<float>(lo), static_cast<float>(lo + kOtsuBins * width)};
  const float* ranges[] = {range};
  const int bins[] = {kOtsuBins};
  const int channels[] = {0};
  assert(size.nx * size.ny < (std::int64_t{1} << 24));  // float counts stay exact
  std::vector<std::uint64_t> histogram(kOtsuBins, 0);
  cv::Mat counts;
  // int16 slices are histogrammed as the floats of their integers (one slice of scratch).
  std::vector<float> scratch(volume.holds_int16() ? static_cast<std::size_t>(size.nx * size.ny)
                                                  : 0);
  for (std::int64_t k = 0; k < size.nz; ++k) {
    const float* values = nullptr;
    if (volume.holds_int16()) {
      const std::int16_t* stored = volume.int16_slice(k);
      std::copy(stored, stored + scratch.size(), scratch.begin());
      values = scratch.data();
    } else {
      values = volume.slice(k);
    }
    const cv::Mat slice(static_cast<int>(size.ny), static_cast<int>(size.nx), CV_32F,
                        const_cast<float*>(values));
    cv::calcHist(&slice, 1, channels, cv::Mat(), counts, 1, bins, ranges);
    for (int b = 0; b < kOtsuBins; ++b) {
      histogram[static_cast<std::size_t>(b)] += static_cast<std::uint64_t>(counts.at<float>(b));
    }
  }
  const int split = detail::otsu_split(histogram);

  OtsuThreshold result;
  result.bin_width = width;
  result.threshold = lo + split * width;
  double n[2] = {0, 0}, sum[2] = {0, 0}, square[2] = {0, 0};
  for (int b = 0; b < kOtsuBins; ++b) {
    const int c = b < split ? 0 : 1;
    const double count = static_cast<double>(histogram[static_cast<std::size_t>(b)]);
    const double value = lo + (b + 0.5) * width;
    n[c] += count;
    sum[c] += count * value;
    square[c] += count * value * value;
  }
  const double all = n[0] + n[1];
  result.lower_mean = n[0] > 0 ? sum[0] / n[0] : lo;
  result.upper_mean = n[1] > 0 ? sum[1] / n[1] : hi;
  result.upper_fraction = n[1] / all;
  const double mean = (sum[0] + sum[1]) / all;
  const double variance = (square[0] + square[1]) / all - mean * mean;
  const double between = n[0] / all * (result.lower_mean - mean) * (result.lower_mean - mean) +
                         n[1] / all * (result.upper_mean - mean) * (result.upper_mean - mean);
  result.separability = variance > 0 ? std::clamp(between / variance, 0.0, 1.0) : 0.0;
  return result;
}

}  // namespace typemerge::preprocess
