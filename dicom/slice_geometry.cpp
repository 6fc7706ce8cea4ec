#include "dicom/slice_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace typemerge::dicom {
namespace {

using core::Vec3;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

std::string mm(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g mm", value);
  return text;
}

std::string file_name(const SliceHeader& slice) {
  std::string name = slice.path.filename().string();
  if (slice.frames_in_file > 1) name += " frame " + std::to_string(slice.frame + 1);
  return name;
}

}  // namespace

bool orientation_frame(const std::array<double, 6>& orientation, Vec3& row, Vec3& col, Vec3& normal,
                       double tolerance) {
  row = {orientation[0], orientation[1], orientation[2]};
  col = {orientation[3], orientation[4], orientation[5]};
  const double row_length = norm(row), col_length = norm(col);
  // Scanners write 6–8 significant digits; 1e-3 accepts their rounding, not a wrong vector.
  if (std::abs(row_length - 1) > 10 * tolerance || std::abs(col_length - 1) > 10 * tolerance) {
    return false;
  }
  row = scale(row, 1 / row_length);
  col = scale(col, 1 / col_length);
  if (std::abs(dot(row, col)) > 10 * tolerance) return false;
  normal = cross(row, col);
  normal = scale(normal, 1 / norm(normal));
  return true;
}

StackGeometry compute_stack_geometry(const std::vector<SliceHeader>& slices,
                                     const GeometryOptions& options) {
  StackGeometry geometry;
  if (slices.empty()) {
    geometry.error = "no slices";
    return geometry;
  }
  const SliceHeader& first = slices.front();
  Vec3 row, col, normal;
  if (!first.orientation || !orientation_frame(*first.orientation, row, col, normal,
                                               options.orientation_tolerance)) {
    geometry.error = "ImageOrientationPatient is not two orthogonal unit vectors";
    return geometry;
  }

  // Order along the normal; equal offsets keep a deterministic order by file and frame.
  std::vector<std::size_t> order(slices.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> offset(slices.size());
  for (std::size_t s = 0; s < slices.size(); ++s) offset[s] = dot(*slices[s].position, normal);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (offset[a] != offset[b]) return offset[a] < offset[b];
    if (slices[a].path != slices[b].path) return slices[a].path < slices[b].path;
    return slices[a].frame < slices[b].frame;
  });

  // Duplicates (the same SOP instance and frame, e.g. a file copied twice) are dropped; two
  // different images at one position would be stacked silently wrong, so they are an error.
  constexpr double kSamePositionMm = 1e-3;
  for (std::size_t k = 0; k < order.size(); ++k) {
    const SliceHeader& slice = slices[order[k]];
    if (!geometry.order.empty()) {
      const SliceHeader& previous = slices[geometry.order.back()];
      if (std::abs(offset[order[k]] - offset[geometry.order.back()]) < kSamePositionMm) {
        if (!slice.sop_instance_uid.empty() && slice.sop_instance_uid == previous.sop_instance_uid &&
            slice.frame == previous.frame) {
          geometry.dropped.push_back(file_name(slice));
          geometry.warnings.push_back("duplicate image " + file_name(slice) + " (same as " +
                                      file_name(previous) + ") dropped");
          continue;
        }
        geometry.error = "two different images at the same position: " + file_name(previous) +
                         " and " + file_name(slice);
        return geometry;
      }
    }
    geometry.order.push_back(order[k]);
    geometry.positions.push_back(*slice.position);
    geometry.normal_offsets.push_back(offset[order[k]]);
  }

  const auto& spacing = *first.pixel_spacing;  // between rows, between columns
  geometry.index_to_patient.origin = geometry.positions.front();
  geometry.index_to_patient.axes[0] = scale(row, spacing[1]);
  geometry.index_to_patient.axes[1] = scale(col, spacing[0]);

  const std::size_t n = geometry.order.size();
  if (n < 2) {
    geometry.error = "a single slice is not a volume";
    return geometry;
  }

  // Positions must lie on one line: a uniform shear (gantry tilt) is exact, anything else
  // (jittering in-plane positions) has no affine grid.
  const Vec3 span = sub(geometry.positions.back(), geometry.positions.front());
  const double depth = geometry.normal_offsets.back() - geometry.normal_offsets.front();
  const Vec3 per_mm = scale(span, 1 / depth);  // position change per mm along the normal
  const double line_tolerance = 0.01 + 0.05 * std::min(spacing[0], spacing[1]);
  for (std::size_t k = 0; k < n; ++k) {
    const double along = geometry.normal_offsets[k] - geometry.normal_offsets.front();
    const Vec3 expected = sub(geometry.positions[k], scale(per_mm, along));
    if (norm(sub(expected, geometry.positions.front())) > line_tolerance) {
      geometry.error = "slice positions do not lie on a line (slice " +
                       file_name(slices[geometry.order[k]]) + " is off by " +
                       mm(norm(sub(expected, geometry.positions.front()))) + ")";
      return geometry;
    }
  }
  geometry.tilt_degrees = std::acos(std::min(1.0, 1 / norm(per_mm))) * 180 / M_PI;
  if (geometry.tilt_degrees > 0.01) {
    char text[96];
    std::snprintf(text, sizeof text, "gantry tilt of %.2f degrees: kept as a sheared grid",
                  geometry.tilt_degrees);
    geometry.warnings.emplace_back(text);
  }

  std::vector<double> steps(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    steps[k] = geometry.normal_offsets[k + 1] - geometry.normal_offsets[k];
  }
  std::vector<double> sorted_steps = steps;
  std::nth_element(sorted_steps.begin(), sorted_steps.begin() + (n - 1) / 2, sorted_steps.end());
  const double median = sorted_steps[(n - 1) / 2];
  const double tolerance = std::max(options.relative_spacing_tolerance * median, 1e-4);

  std::vector<std::string> irregularities;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    if (std::abs(steps[k] - median) <= tolerance) continue;
    const double ratio = steps[k] / median;
    const double whole = std::round(ratio);
    std::string where = "between " + file_name(slices[geometry.order[k]]) + " and " +
                        file_name(slices[geometry.order[k + 1]]);
    if (whole >= 2 && std::abs(ratio - whole) * median <= tolerance) {
      // Printed from the double: a gap can be any number of steps (positions are any
      // finite DS), far beyond what an integer type holds.
      char missing[320];  // the largest double has 309 digits
      std::snprintf(missing, sizeof missing, "%.0f", whole - 1);
      irregularities.push_back(std::string(missing) + " missing slice(s) " + where +
                               " (gap of " + mm(steps[k]) + ", step " + mm(median) + ")");
    } else {
      irregularities.push_back("step of " + mm(steps[k]) + " " + where + " (median " +
                               mm(median) + ")");
    }
  }

  if (irregularities.empty()) {
    geometry.slice_step_mm = depth / static_cast<double>(n - 1);
    geometry.output_slices = static_cast<std::int64_t>(n);
    geometry.index_to_patient.axes[2] = scale(span, 1.0 / static_cast<double>(n - 1));
    return geometry;
  }

  std::string summary = "slice spacing is not uniform: " + irregularities.front();
  if (irregularities.size() > 1) {
    summary += " and " + std::to_string(irregularities.size() - 1) + " more irregular step(s)";
  }
  if (options.spacing == SpacingPolicy::refuse) {
    geometry.error = summary + "; resampling is available on request";
    return geometry;
  }
  // Resample at the smallest step, so no acquired slice is thinned out.
  const double step = *std::min_element(steps.begin(), steps.end());
  // Positions are any finite DS, so depth / step can exceed every integer type; a grid of
  // more than 2^31 slices is no CT volume (and would overflow the voxel count).
  const double grid_slices = std::floor(depth / step + 1e-6) + 1;
  if (!(grid_slices <= double{std::numeric_limits<std::int32_t>::max()})) {
    geometry.error = summary + "; resampling at the smallest step (" + mm(step) + ") over " +
                     mm(depth) + " would need more than 2^31 slices";
    return geometry;
  }
  geometry.needs_resampling = true;
  geometry.slice_step_mm = step;
  geometry.output_slices = static_cast<std::int64_t>(grid_slices);
  geometry.index_to_patient.axes[2] = scale(per_mm, step);
  geometry.warnings.push_back(summary + "; resampled linearly to " +
                              std::to_string(geometry.output_slices) + " slices of " + mm(step));
  return geometry;
}

}  // namespace typemerge::dicom
