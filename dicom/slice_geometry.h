// Stack geometry of one series: slice order, spacing, gaps, gantry tilt, index → LPS map.
//
// Slices are ordered by their position projected on the slice normal (never by file name or
// InstanceNumber). Spacing comes from positions, not SliceThickness. A gantry-tilted series
// is recognised because its positions advance along the table, not along the normal; it is
// kept as the sheared grid it is, so surfaces can be placed exactly without resampling.
#pragma once

#include <string>
#include <vector>

#include "core/volume.h"
#include "dicom/slice_header.h"

namespace typemerge::dicom {

enum class SpacingPolicy {
  refuse,    // non-uniform spacing or missing slices: the series is refused (default)
  resample,  // resample onto a uniform grid at the smallest slice step; a warning is recorded
};

struct GeometryOptions {
  SpacingPolicy spacing = SpacingPolicy::refuse;
  double relative_spacing_tolerance = 0.01;  // of the median step
  double orientation_tolerance = 1e-3;       // on dot products of unit vectors (about 2.6°)
};

struct StackGeometry {
  std::vector<std::size_t> order;       // indices into the input slices, along the normal
  std::vector<core::Vec3> positions;    // ImagePositionPatient of each ordered slice
  std::vector<double> normal_offsets;   // position · normal of each ordered slice, mm
  core::IndexToPatient index_to_patient;  // for the (possibly resampled) uniform grid
  std::int64_t output_slices = 0;       // slices of the uniform grid
  bool needs_resampling = false;
  double slice_step_mm = 0;             // distance between grid slices along the normal
  double tilt_degrees = 0;              // angle between the slice step and the normal
  std::vector<std::string> warnings;
  std::vector<std::string> dropped;     // duplicates removed (file names)
  std::string error;                    // non-empty: the series cannot be made a volume

  bool ok() const { return error.empty(); }
};

StackGeometry compute_stack_geometry(const std::vector<SliceHeader>& slices,
                                     const GeometryOptions& options);

// Unit row and column directions and the normal of an ImageOrientationPatient value;
// false when the vectors are not unit length or not orthogonal.
bool orientation_frame(const std::array<double, 6>& orientation, core::Vec3& row, core::Vec3& col,
                       core::Vec3& normal, double tolerance = 1e-3);

}  // namespace typemerge::dicom
