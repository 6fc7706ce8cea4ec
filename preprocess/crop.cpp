#include "preprocess/crop.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace typemerge::preprocess {
namespace {

using core::Vec3;
using core::Volume;

void assert_volume(const Volume& volume) {
  assert(volume.sample_bytes() ==
         static_cast<std::size_t>(volume.size().voxels()) * (volume.holds_int16() ? 2 : 4));
  assert(volume.geometry().determinant() != 0);
  (void)volume;
}

std::int64_t count(const core::VolumeSize& size, int axis) {
  return axis == 0 ? size.nx : axis == 1 ? size.ny : size.nz;
}

// Patient LPS mm → continuous voxel index, by the inverse of [axes] (adjugate / determinant).
Vec3 patient_to_index(const core::IndexToPatient& geometry, const Vec3& point) {
  const auto& a = geometry.axes;  // columns of the matrix M: p − origin = M · index
  const double m[3][3] = {
      {a[0][0], a[1][0], a[2][0]}, {a[0][1], a[1][1], a[2][1]}, {a[0][2], a[1][2], a[2][2]}};
  const double det = geometry.determinant();
  const double d[3] = {point[0] - geometry.origin[0], point[1] - geometry.origin[1],
                       point[2] - geometry.origin[2]};
  Vec3 index{};
  for (int r = 0; r < 3; ++r) {
    // Row r of the inverse is the cross product of columns r+1 and r+2 of M, over det.
    const int s = (r + 1) % 3, t = (r + 2) % 3;
    double row[3];
    for (int c = 0; c < 3; ++c) {
      const int c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      row[c] = m[c1][s] * m[c2][t] - m[c2][s] * m[c1][t];
    }
    index[r] = (row[0] * d[0] + row[1] * d[1] + row[2] * d[2]) / det;
  }
  return index;
}

std::string box_text(const IndexBox& box) {
  std::string text = "[";
  for (int axis = 0; axis < 3; ++axis) {
    text += std::to_string(box.begin[axis]) + ".." + std::to_string(box.end[axis]);
    text += axis < 2 ? ", " : ")";
  }
  return text;
}

IndexBox clamp_box(const IndexBox& box, const core::VolumeSize& size) {
  IndexBox clamped;
  for (int axis = 0; axis < 3; ++axis) {
    clamped.begin[axis] = std::clamp<std::int64_t>(box.begin[axis], 0, count(size, axis));
    clamped.end[axis] = std::clamp<std::int64_t>(box.end[axis], 0, count(size, axis));
  }
  return clamped;
}

}  // namespace

core::VolumeSize IndexBox::size() const {
  if (empty()) return {0, 0, 0};
  return {end[0] - begin[0], end[1] - begin[1], end[2] - begin[2]};
}

IndexBox index_box_of(const Volume& volume, const PatientBox& box) {
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(box.min[c]) || !std::isfinite(box.max[c]) || box.min[c] > box.max[c]) {
      throw std::invalid_argument(
          std::string("crop_to_patient_box: box min must be ≤ max on every axis, got axis ") +
          std::to_string(c) + ": " + detail::format_number(box.min[c]) + " > " +
          detail::format_number(box.max[c]));
    }
  }
  assert_volume(volume);
  Vec3 low{}, high{};
  low.fill(std::numeric_limits<double>::infinity());
  high.fill(-std::numeric_limits<double>::infinity());
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 point{(corner & 1) ? box.max[0] : box.min[0], (corner & 2) ? box.max[1] : box.min[1],
                     (corner & 4) ? box.max[2] : box.min[2]};
    const Vec3 index = patient_to_index(volume.geometry(), point);
    for (int axis = 0; axis < 3; ++axis) {
      low[axis] = std::min(low[axis], index[axis]);
      high[axis] = std::max(high[axis], index[axis]);
    }
  }
  // Voxel centres on the box's faces are inside; the tolerance absorbs the inverse's rounding.
  constexpr double kTolerance = 1e-6;
  IndexBox result;
  for (int axis = 0; axis < 3; ++axis) {
    const double n = static_cast<double>(count(volume.size(), axis));
    result.begin[axis] =
        static_cast<std::int64_t>(std::clamp(std::ceil(low[axis] - kTolerance), 0.0, n));
    result.end[axis] =
        static_cast<std::int64_t>(std::clamp(std::floor(high[axis] + kTolerance) + 1, 0.0, n));
  }
  return result;
}

IndexBox tissue_bounding_box(const Volume& volume, float threshold_hu) {
  assert_volume(volume);
  const auto& size = volume.size();
  IndexBox box{{size.nx, size.ny, size.nz}, {0, 0, 0}};
  volume.visit([&](const auto* samples) {
    for (std::int64_t k = 0; k < size.nz; ++k) {
      for (std::int64_t j = 0; j < size.ny; ++j) {
        const auto* row = samples + (k * size.ny + j) * size.nx;
        std::int64_t first = 0;
        while (first < size.nx && !(row[first] >= threshold_hu)) ++first;
        if (first == size.nx) continue;
        std::int64_t last = size.nx - 1;
        while (!(row[last] >= threshold_hu)) --last;
        box.begin = {std::min(box.begin[0], first), std::min(box.begin[1], j),
                     std::min(box.begin[2], k)};
        box.end = {std::max(box.end[0], last + 1), std::max(box.end[1], j + 1),
                   std::max(box.end[2], k + 1)};
      }
    }
  });
  if (box.empty()) return IndexBox{};
  return box;
}

StepResult crop(const Volume& volume, const IndexBox& box) {
  assert_volume(volume);
  const IndexBox kept = clamp_box(box, volume.size());
  if (kept.empty()) {
    throw std::invalid_argument("crop: the box " + box_text(box) + " does not overlap the " +
                                detail::format_size(volume.size()) + " volume");
  }
  const core::VolumeSize out = kept.size();
  core::IndexToPatient geometry = volume.geometry();
  geometry.origin =
      geometry.apply(static_cast<double>(kept.begin[0]), static_cast<double>(kept.begin[1]),
                     static_cast<double>(kept.begin[2]));
  // The same storage as the input; every sample is copied.
  StepResult result{Volume::uninitialized(out, geometry, volume.sample_type()), {}};
  const auto copy = [&](const auto* from, auto* to) {
    for (std::int64_t k = 0; k < out.nz; ++k) {
      for (std::int64_t j = 0; j < out.ny; ++j) {
        std::copy_n(from + ((kept.begin[2] + k) * volume.size().ny + kept.begin[1] + j) *
                               volume.size().nx + kept.begin[0],
                    out.nx, to + (k * out.ny + j) * out.nx);
      }
    }
  };
  if (volume.holds_int16()) {
    copy(volume.int16_samples().data(), result.volume.int16_samples().data());
  } else {
    copy(volume.samples().data(), result.volume.samples().data());
  }
  StepRecord& record = result.record;
  record.step = "crop";
  record.size_before = volume.size();
  record.size_after = out;
  for (int axis = 0; axis < 3; ++axis) {
    const char* name[] = {"i", "j", "k"};
    record.parameters.emplace_back(std::string("begin_") + name[axis],
                                   std::to_string(kept.begin[axis]));
    record.parameters.emplace_back(std::string("end_") + name[axis],
                                   std::to_string(kept.end[axis]));
  }
  if (!(kept == box)) {
    record.warnings.push_back("crop: the box " + box_text(box) +
                              " was clamped to the volume: " + box_text(kept));
  }
  record.description = std::string("crop to voxels ") + box_text(kept) + ": " +
                       detail::format_size(volume.size()) + " → " + detail::format_size(out);
  return result;
}

StepResult crop_to_patient_box(const Volume& volume, const PatientBox& box) {
  const IndexBox indices = index_box_of(volume, box);
  const auto mm = [](const Vec3& p) {
    return std::string("(") + detail::format_number(p[0]) + ", " + detail::format_number(p[1]) +
           ", " + detail::format_number(p[2]) + ")";
  };
  if (indices.empty()) {
    throw std::invalid_argument("crop_to_patient_box: no voxel centre lies in the box " +
                                mm(box.min) + "–" + mm(box.max) + " mm");
  }
  StepResult result = crop(volume, indices);
  result.record.step = "crop_to_patient_box";
  result.record.parameters.insert(result.record.parameters.begin(),
                                  {{"min_lps_mm", mm(box.min)}, {"max_lps_mm", mm(box.max)}});
  result.record.description = std::string("crop to LPS box ") + mm(box.min) + "–" + mm(box.max) +
                              " mm = " + result.record.description.substr(5);  // drop "crop "
  return result;
}

StepResult crop_to_tissue(const Volume& volume, const TissueCropOptions& options) {
  if (!std::isfinite(options.threshold_hu)) {
    throw std::invalid_argument("crop_to_tissue: threshold_hu must be finite");
  }
  if (!std::isfinite(options.margin_mm) || options.margin_mm < 0) {
    throw std::invalid_argument("crop_to_tissue: margin_mm must be ≥ 0, got " +
                                detail::format_number(options.margin_mm));
  }
  const IndexBox tissue = tissue_bounding_box(volume, options.threshold_hu);
  const std::vector<std::pair<std::string, std::string>> parameters = {
      {"threshold_hu", detail::format_number(options.threshold_hu)},
      {"margin_mm", detail::format_number(options.margin_mm)},
      {"tissue_found", tissue.empty() ? "false" : "true"}};
  if (tissue.empty()) {
    StepResult unchanged{volume, {}};
    unchanged.record.step = "crop_to_tissue";
    unchanged.record.size_before = unchanged.record.size_after = volume.size();
    unchanged.record.parameters = parameters;
    unchanged.record.warnings.push_back("crop_to_tissue: no voxel ≥ " +
                                        detail::format_number(options.threshold_hu) +
                                        " HU; the volume is left uncropped");
    unchanged.record.description = "no tissue found, not cropped";
    return unchanged;
  }
  IndexBox box = tissue;
  for (int axis = 0; axis < 3; ++axis) {
    const auto margin = static_cast<std::int64_t>(
        std::ceil(options.margin_mm / volume.geometry().spacing(axis) - 1e-9));
    box.begin[axis] = std::max<std::int64_t>(tissue.begin[axis] - margin, 0);
    box.end[axis] = std::min(tissue.end[axis] + margin, count(volume.size(), axis));
  }
  StepResult result = crop(volume, box);  // clamped above: no clamping warning
  result.record.step = "crop_to_tissue";
  result.record.parameters.insert(result.record.parameters.begin(), parameters.begin(),
                                  parameters.end());
  result.record.description =
      std::string("crop to tissue ≥ ") + detail::format_number(options.threshold_hu) + " HU (box " +
      box_text(tissue) + ") with " + detail::format_number(options.margin_mm) +
      " mm margin: " + result.record.description.substr(5);
  return result;
}

}  // namespace typemerge::preprocess
