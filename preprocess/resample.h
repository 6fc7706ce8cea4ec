// Resampling a CT volume onto a new voxel size with exact geometry.
//
// Convention kept: the origin is the centre of voxel (0,0,0) before and after, and each index
// axis is scaled, so new voxel (i', j', k') sits exactly where the old index
// (i'·s'_i/s_i, j'·s'_j/s_j, k'·s'_k/s_k) sits, in patient space too — also on a sheared
// (gantry-tilt) grid, whose axes keep their directions. The new grid covers the old one from
// voxel 0 and never extends past the old last voxel centre, so nothing is extrapolated:
//   n' = floor((n − 1) · s / s') + 1  per axis.
// Interpolation is trilinear (separable linear in k, j, i): a field linear in patient mm is
// reproduced exactly up to float rounding.
//
// Memory: the output plus two slices of scratch; the input is not modified (peak = input +
// output + 2 slices). downsample(factor 2) needs 1/8 of the input extra. Given the input with
// std::move (the Volume&& overloads), its storage is returned to the OS as its slices are read
// for the last time and freed on return (the moved-from volume is empty): peak = output +
// 2 slices + 2 MiB. The result is the same for either overload and either sample storage.
//
// Preconditions (asserted): samples().size() == size().voxels(), positive spacings.
// Invalid options throw std::invalid_argument naming the option.
#pragma once

#include <cstdint>

#include "core/volume.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess {

struct ResampleOptions {
  core::Vec3 voxel_size_mm{1, 1, 1};  // new spacing along i, j, k; each > 0
  // Refused before allocating (std::invalid_argument): guards against a typo such as 0.01 mm.
  std::int64_t max_output_voxels = std::int64_t{1} << 31;
};

struct IsotropicOptions {
  double voxel_size_mm = 0;  // ≥ 0; 0 means the smallest of the current spacings
  std::int64_t max_output_voxels = std::int64_t{1} << 31;
};

struct DownsampleOptions {
  int factor = 2;  // ≥ 1: keeps every factor-th voxel along each axis (no anti-aliasing
                   // prefilter: for quick previews; run gaussian_filter first for a clean one)
};

StepResult resample(const core::Volume& volume, const ResampleOptions& options);
StepResult resample_isotropic(const core::Volume& volume, const IsotropicOptions& options = {});
StepResult resample(core::Volume&& volume, const ResampleOptions& options);
StepResult resample_isotropic(core::Volume&& volume, const IsotropicOptions& options = {});
StepResult downsample(const core::Volume& volume, const DownsampleOptions& options = {});

}  // namespace typemerge::preprocess
