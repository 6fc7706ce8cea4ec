#include "preprocess/body_mask.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace typemerge::preprocess {
namespace {

// An elliptical structuring element of `radius_mm` for anisotropic pixels.
cv::Mat disk(double radius_mm, double spacing_x, double spacing_y) {
  const int rx = std::max(1, static_cast<int>(std::lround(radius_mm / spacing_x)));
  const int ry = std::max(1, static_cast<int>(std::lround(radius_mm / spacing_y)));
  return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
}

// Labels 6-connected components of `mask` (non-zero voxels) and keeps the largest one. A
// breadth-first flood fill written here because OpenCV's connected components are 2D only.
// Returns the number of components found.
std::size_t keep_largest_component(std::vector<std::uint8_t>& mask, const core::VolumeSize& size) {
  const std::int64_t nx = size.nx, ny = size.ny, nz = size.nz;
  std::vector<std::int32_t> label(mask.size(), 0);
  std::vector<std::int64_t> queue;
  std::int32_t components = 0, best = 0;
  std::int64_t best_size = 0;
  for (std::int64_t start = 0; start < static_cast<std::int64_t>(mask.size()); ++start) {
    if (!mask[start] || label[start] != 0) continue;
    const std::int32_t current = ++components;
    std::int64_t count = 0;
    queue.assign(1, start);
    label[start] = current;
    while (!queue.empty()) {
      const std::int64_t v = queue.back();
      queue.pop_back();
      ++count;
      const std::int64_t x = v % nx, y = (v / nx) % ny, z = v / (nx * ny);
      const std::int64_t neighbours[6][2] = {{x > 0, v - 1},       {x + 1 < nx, v + 1},
                                             {y > 0, v - nx},      {y + 1 < ny, v + nx},
                                             {z > 0, v - nx * ny}, {z + 1 < nz, v + nx * ny}};
      for (const auto& [inside, n] : neighbours) {
        if (inside && mask[n] && label[n] == 0) {
          label[n] = current;
          queue.push_back(n);
        }
      }
    }
    if (count > best_size) {
      best_size = count;
      best = current;
    }
  }
  for (std::size_t v = 0; v < mask.size(); ++v) mask[v] = label[v] == best && best != 0;
  return static_cast<std::size_t>(components);
}

}  // namespace

StepResult remove_outside_body(core::Volume volume, const BodyMaskOptions& options) {
  if (!(options.opening_mm > 0) || !(options.margin_mm >= 0)) {
    throw std::invalid_argument("body mask: opening_mm must be > 0 and margin_mm >= 0");
  }
  const core::VolumeSize size = volume.size();
  const auto slice_voxels = static_cast<std::size_t>(size.nx * size.ny);
  const int rows = static_cast<int>(size.ny), cols = static_cast<int>(size.nx);
  const double sx = volume.geometry().spacing(0), sy = volume.geometry().spacing(1);

  std::vector<std::uint8_t> dense(volume.samples().size());
  std::vector<std::uint8_t> seed(volume.samples().size());
  const cv::Mat opening = disk(options.opening_mm, sx, sy);
  for (std::int64_t k = 0; k < size.nz; ++k) {
    const float* in = volume.slice(k);
    std::uint8_t* d = dense.data() + k * slice_voxels;
    for (std::size_t p = 0; p < slice_voxels; ++p) d[p] = in[p] > options.air_threshold_hu ? 255 : 0;
    const cv::Mat dense_slice(rows, cols, CV_8U, d);
    cv::Mat seed_slice(rows, cols, CV_8U, seed.data() + k * slice_voxels);
    cv::morphologyEx(dense_slice, seed_slice, cv::MORPH_OPEN, opening);
  }
  const std::size_t components = keep_largest_component(seed, size);

  StepRecord record;
  record.step = "remove_outside_body";
  record.size_before = record.size_after = size;
  record.parameters = {{"air_threshold_hu", detail::format_number(options.air_threshold_hu)},
                       {"opening_mm", detail::format_number(options.opening_mm)},
                       {"margin_mm", detail::format_number(options.margin_mm)}};
  if (components == 0) {
    record.description = "no body found (nothing denser than air after the opening); unchanged";
    record.warnings.push_back("no body found: nothing was removed");
    return {std::move(volume), std::move(record)};
  }
  // Grow the body back in-plane and by one slice, inside the original dense mask.
  const cv::Mat grow = disk(options.opening_mm + options.margin_mm, sx, sy);
  std::vector<std::uint8_t> keep(volume.samples().size());
  for (std::int64_t k = 0; k < size.nz; ++k) {
    cv::Mat grown;
    cv::Mat seed_slice(rows, cols, CV_8U, seed.data() + k * slice_voxels);
    cv::Mat here = seed_slice * 255;
    for (std::int64_t dk : {k - 1, k + 1}) {
      if (dk < 0 || dk >= size.nz) continue;
      here = cv::max(here, cv::Mat(rows, cols, CV_8U, seed.data() + dk * slice_voxels) * 255);
    }
    cv::dilate(here, grown, grow);
    std::uint8_t* out = keep.data() + k * slice_voxels;
    const std::uint8_t* d = dense.data() + k * slice_voxels;
    for (std::size_t p = 0; p < slice_voxels; ++p) out[p] = grown.data[p] && d[p];
  }
  std::int64_t cleared = 0;
  for (std::size_t v = 0; v < keep.size(); ++v) {
    if (dense[v] && !keep[v]) {
      volume.samples()[v] = -1000.0f;
      ++cleared;
    }
  }
  record.parameters.emplace_back("components", std::to_string(components));
  record.parameters.emplace_back("cleared_voxels", std::to_string(cleared));
  record.description = "kept the largest of " + std::to_string(components) +
                       " dense components (the body); " + std::to_string(cleared) +
                       " voxels outside it set to air";
  return {std::move(volume), std::move(record)};
}

}  // namespace typemerge::preprocess
