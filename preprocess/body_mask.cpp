#include "preprocess/body_mask.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

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
  if (!(options.opening_mm > 0) || !(options.restore_mm >= 0) || !(options.edge_mm >= 0) ||
      !(options.body_threshold_hu >= options.air_threshold_hu)) {
    throw std::invalid_argument(
        "body mask: opening_mm must be > 0, restore_mm and edge_mm >= 0, and the body "
        "threshold at or above the air threshold");
  }
  const core::VolumeSize size = volume.size();
  const auto slice_voxels = static_cast<std::size_t>(size.nx * size.ny);
  const int rows = static_cast<int>(size.ny), cols = static_cast<int>(size.nx);
  const double sx = volume.geometry().spacing(0), sy = volume.geometry().spacing(1);
  auto slice_mat = [&](std::vector<std::uint8_t>& mask, std::int64_t k) {
    return cv::Mat(rows, cols, CV_8U, mask.data() + k * std::int64_t(slice_voxels));
  };
  // Slices are independent in steps 1, 3 and 4: TBB runs them on every core.
  auto each_slice = [&](auto&& body) {
    tbb::parallel_for(std::int64_t{0}, size.nz, [&](std::int64_t k) { body(k); });
  };

  // 1–2. Tissue, opened in-plane; the seed is its largest 3D component.
  std::vector<std::uint8_t> tissue(volume.samples().size());
  std::vector<std::uint8_t> seed(volume.samples().size());
  const cv::Mat opening = disk(options.opening_mm, sx, sy);
  each_slice([&](std::int64_t k) {
    const float* in = volume.slice(k);
    std::uint8_t* t = tissue.data() + k * std::int64_t(slice_voxels);
    for (std::size_t p = 0; p < slice_voxels; ++p) t[p] = in[p] > options.body_threshold_hu ? 255 : 0;
    cv::Mat seed_slice = slice_mat(seed, k);
    cv::morphologyEx(slice_mat(tissue, k), seed_slice, cv::MORPH_OPEN, opening);
  });
  const std::size_t components = keep_largest_component(seed, size);

  StepRecord record;
  record.step = "remove_outside_body";
  record.size_before = record.size_after = size;
  record.parameters = {{"air_threshold_hu", detail::format_number(options.air_threshold_hu)},
                       {"body_threshold_hu", detail::format_number(options.body_threshold_hu)},
                       {"opening_mm", detail::format_number(options.opening_mm)},
                       {"restore_mm", detail::format_number(options.restore_mm)},
                       {"edge_mm", detail::format_number(options.edge_mm)}};
  if (components == 0) {
    record.description = "no body found (no tissue after the opening); unchanged";
    record.warnings.push_back("no body found: nothing was removed");
    return {std::move(volume), std::move(record)};
  }

  // 3. The body: tissue within reach of the seed (this slice or a neighbour).
  std::vector<std::uint8_t> body(volume.samples().size());
  const cv::Mat restore = disk(options.opening_mm + options.restore_mm, sx, sy);
  each_slice([&](std::int64_t k) {
    cv::Mat near = slice_mat(seed, k) * 255;
    for (std::int64_t n : {k - 1, k + 1}) {
      if (n >= 0 && n < size.nz) near = cv::max(near, slice_mat(seed, n) * 255);
    }
    cv::Mat grown;
    cv::dilate(near, grown, restore);
    cv::Mat body_slice = slice_mat(body, k);
    cv::bitwise_and(grown, slice_mat(tissue, k), body_slice);
  });

  // 4. Keep the body and its partial-volume edge; clear whatever else is denser than air.
  std::vector<std::int64_t> cleared_in_slice(static_cast<std::size_t>(size.nz), 0);
  const cv::Mat edge = options.edge_mm > 0 ? disk(options.edge_mm, sx, sy) : cv::Mat();
  each_slice([&](std::int64_t k) {
    cv::Mat near = slice_mat(body, k).clone();
    for (std::int64_t n : {k - 1, k + 1}) {
      if (n >= 0 && n < size.nz) near = cv::max(near, slice_mat(body, n));
    }
    cv::Mat keep = near;
    if (!edge.empty()) cv::dilate(near, keep, edge);
    float* values = volume.slice(k);
    std::int64_t cleared = 0;
    for (std::size_t p = 0; p < slice_voxels; ++p) {
      if (values[p] > options.air_threshold_hu && keep.data[p] == 0) {
        values[p] = -1000.0f;
        ++cleared;
      }
    }
    cleared_in_slice[static_cast<std::size_t>(k)] = cleared;
  });
  std::int64_t cleared = 0;
  for (std::int64_t c : cleared_in_slice) cleared += c;
  record.parameters.emplace_back("components", std::to_string(components));
  record.parameters.emplace_back("cleared_voxels", std::to_string(cleared));
  record.description = "kept the largest of " + std::to_string(components) +
                       " tissue components (the body) and its edge; " + std::to_string(cleared) +
                       " voxels outside it set to air";
  return {std::move(volume), std::move(record)};
}

}  // namespace typemerge::preprocess
