// Denoising filters on a CT volume: Gaussian, median and bilateral (edge-preserving), in 3D.
//
// Each filter is separable in the same way: OpenCV filters every slice in-plane, then a
// hand-written 1D pass runs along the slice axis k, so that the result is 3D and a feature one
// slice thick is treated like one a voxel wide in-plane.
//
//   gaussian_filter   exact 3D Gaussian (a Gaussian is separable), sigma in mm per axis.
//   median_filter     cv::medianBlur 3×3 or 5×5 per slice, then a 3-tap median along k.
//                     Not a true 3×3×3 median: it removes an outlier isolated in any direction
//                     and a plate one slice thick, but a 2×2×2 clump survives both passes.
//   bilateral_filter  cv::bilateralFilter per slice, then a 1D bilateral along k with the same
//                     spatial sigma (mm) and range sigma (HU): the separable approximation of
//                     Pham & van Vliet, "Separable bilateral filtering for fast video
//                     preprocessing", ICME 2005. Edges stronger than ~3·sigma_hu are kept.
//
// Sheared (gantry-tilt) grids: the k pass filters along the slice step axes[2], whose length
// is the spacing used; the kernel is then a Gaussian in the sheared frame, not a rotationally
// symmetric one in patient space. For tilts of a few degrees the difference is negligible.
//
// Output: float storage (filtered values are not integers). Memory, besides a scratch of one
// slice and one nx×nz plane: a float volume is filtered in place (pass it with std::move to
// avoid the copy): peak ≈ 4 bytes a voxel. An int16 volume is read slice by slice into the
// new float volume, and the input's storage is returned to the OS (Linux) as its slices are
// read, so the two are not held whole together: peak ≈ 4 bytes a voxel + 2 MiB, where a
// whole-volume conversion first would hold 6. The result is the same for both storages.
//
// Preconditions (asserted): the samples fill the volume, positive spacings, nx and ny fit in
// an int. Invalid options throw std::invalid_argument naming the option.
#pragma once

#include "core/volume.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess {

struct GaussianOptions {
  double sigma_mm = 0.7;  // > 0; per-axis voxel sigma = sigma_mm / spacing(axis)
  double truncate = 3.0;  // kernel radius in sigmas (≥ 1): radius = ceil(truncate · sigma_voxels)
};

struct MedianOptions {
  int in_plane_size = 3;     // 3 or 5 (cv::medianBlur supports float only for these)
  bool along_slices = true;  // then a 3-tap median along k
};

struct BilateralOptions {
  double sigma_mm = 1.0;   // > 0; spatial sigma; window radius = round(1.5 · sigma_voxels), ≥ 1
  double sigma_hu = 60.0;  // > 0; range sigma: differences ≫ sigma_hu do not mix (edges kept)
  bool along_slices = true;  // then the 1D bilateral along k
};

// Empty volumes are returned unchanged (with a record saying so).
StepResult gaussian_filter(core::Volume volume, const GaussianOptions& options = {});
StepResult median_filter(core::Volume volume, const MedianOptions& options = {});
StepResult bilateral_filter(core::Volume volume, const BilateralOptions& options = {});

}  // namespace typemerge::preprocess
