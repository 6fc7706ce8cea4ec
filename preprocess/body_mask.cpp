#include "preprocess/body_mask.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "preprocess/run_mask.h"

namespace typemerge::preprocess {
namespace {

// OpenCV's elliptical structuring element of `radius_mm` for anisotropic pixels, as runs.
runs::Kernel disk(double radius_mm, double spacing_x, double spacing_y) {
  const int rx = std::max(1, static_cast<int>(std::lround(radius_mm / spacing_x)));
  const int ry = std::max(1, static_cast<int>(std::lround(radius_mm / spacing_y)));
  return runs::ellipse_kernel(rx, ry);
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
  const auto nz = static_cast<std::size_t>(size.nz);
  const auto rows = static_cast<std::int32_t>(size.ny), cols = static_cast<std::int32_t>(size.nx);
  const double sx = volume.geometry().spacing(0), sy = volume.geometry().spacing(1);
  // A slice of `mask` joined with its neighbours: what lies within one slice in z.
  auto near_slices = [&](const std::vector<runs::SliceRuns>& mask, std::size_t k) {
    runs::SliceRuns near = mask[k];
    if (k > 0) near = runs::unite(near, mask[k - 1]);
    if (k + 1 < nz) near = runs::unite(near, mask[k + 1]);
    return near;
  };
  // Slices are independent in steps 1, 3 and 4: TBB runs them on every core.
  auto each_slice = [&](auto&& body) {
    tbb::parallel_for(std::size_t{0}, nz, [&](std::size_t k) { body(k); });
  };

  // 1–2. Tissue, opened in-plane; the seed is its largest 3D component.
  // Denser than air too, while the slice is in cache: what step 4 may clear.
  std::vector<runs::SliceRuns> tissue(nz), seed(nz), dense(nz);
  const runs::Kernel opening = disk(options.opening_mm, sx, sy);
  each_slice([&](std::size_t k) {
    volume.visit([&](const auto* samples) {
      const auto* values = samples + k * static_cast<std::size_t>(rows) * cols;
      tissue[k] = runs::threshold_above(values, cols, rows, options.body_threshold_hu);
      dense[k] = runs::threshold_above(values, cols, rows, options.air_threshold_hu);
    });
    seed[k] = runs::dilate(runs::erode(tissue[k], opening), opening);
  });
  const std::size_t components = runs::keep_largest_component(seed);

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
  std::vector<runs::SliceRuns> body(nz);
  const runs::Kernel restore = disk(options.opening_mm + options.restore_mm, sx, sy);
  each_slice([&](std::size_t k) {
    body[k] = runs::intersect(runs::dilate(near_slices(seed, k), restore), tissue[k]);
  });

  // 4. Keep the body and its partial-volume edge (into `seed`, free now); clear whatever else
  //    is denser than air — unless that would clear much of the tissue: then the body was
  //    not found (a dry skull phantom is a thin shell the opening breaks up, and its holder
  //    became the largest component), and the volume is left as it is, with a warning.
  std::vector<runs::SliceRuns>& keep = seed;
  std::vector<std::int64_t> tissue_in_slice(nz, 0);
  std::vector<std::int64_t> tissue_out_in_slice(nz, 0);
  const bool grow_edge = options.edge_mm > 0;
  const runs::Kernel edge = grow_edge ? disk(options.edge_mm, sx, sy) : runs::Kernel{};
  each_slice([&](std::size_t k) {
    runs::SliceRuns near = near_slices(body, k);
    const std::int64_t all = static_cast<std::int64_t>(tissue[k].count());
    keep[k] = grow_edge ? runs::dilate(near, edge) : std::move(near);
    tissue_in_slice[k] = all;
    tissue_out_in_slice[k] =
        all - static_cast<std::int64_t>(runs::intersect(tissue[k], keep[k]).count());
  });
  std::int64_t tissue_total = 0, tissue_outside = 0;
  for (std::size_t k = 0; k < tissue_in_slice.size(); ++k) {
    tissue_total += tissue_in_slice[k];
    tissue_outside += tissue_out_in_slice[k];
  }
  const double outside_fraction =
      tissue_total > 0 ? double(tissue_outside) / double(tissue_total) : 0.0;
  record.parameters.emplace_back("components", std::to_string(components));
  record.parameters.emplace_back("tissue_outside_fraction", detail::format_number(outside_fraction));
  if (outside_fraction > options.max_tissue_outside_fraction) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "table removal skipped: %.0f %% of the tissue lies outside the largest "
                  "component, so it is not a body lying on a table (a phantom?); use --crop-mm "
                  "to leave out a holder",
                  100.0 * outside_fraction);
    record.warnings.push_back(text);
    record.parameters.emplace_back("cleared_voxels", "0");
    record.description = text;
    return {std::move(volume), std::move(record)};
  }
  std::vector<std::int64_t> cleared_in_slice(nz, 0);
  each_slice([&](std::size_t k) {
    // Only what is denser than air and outside the body is written; nothing else is read.
    const runs::SliceRuns clear = runs::subtract(dense[k], keep[k]);
    auto fill = [&](auto* values, auto air) {
      for (std::int32_t y = 0; y < rows; ++y) {
        auto* row = values + static_cast<std::ptrdiff_t>(y) * cols;
        for (const runs::Run* r = clear.row_begin(y); r != clear.row_end(y); ++r) {
          std::fill(row + r->begin, row + r->end, air);
        }
      }
    };
    // Air is −1000 in either storage.
    const auto slice = static_cast<std::int64_t>(k);
    if (volume.holds_int16()) {
      fill(volume.int16_slice(slice), std::int16_t{-1000});
    } else {
      fill(volume.slice(slice), -1000.0f);
    }
    const auto cleared = static_cast<std::int64_t>(clear.count());
    cleared_in_slice[k] = cleared;
  });
  std::int64_t cleared = 0;
  for (std::int64_t c : cleared_in_slice) cleared += c;
  record.parameters.emplace_back("cleared_voxels", std::to_string(cleared));
  char text[160];
  std::snprintf(text, sizeof text, "%.1f %% of the tissue", 100.0 * outside_fraction);
  record.description = "kept the largest of " + std::to_string(components) +
                       " tissue components (the body) and its edge; " + std::to_string(cleared) +
                       " voxels outside it set to air (" + text + ")";
  return {std::move(volume), std::move(record)};
}

}  // namespace typemerge::preprocess
