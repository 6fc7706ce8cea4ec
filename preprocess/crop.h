// Cropping a CT volume: to a box of voxel indices, to a box in patient millimetres, or to the
// bounding box of the tissue.
//
// The axes are unchanged and the new origin is the patient position of the first kept voxel,
// origin + i0·axes[0] + j0·axes[1] + k0·axes[2], so every kept voxel keeps its exact patient
// position (also on sheared, gantry-tilted grids).
//
// Memory: the output (at most the input's size); the input is not modified.
// Preconditions (asserted): samples().size() == size().voxels(), an invertible geometry.
#pragma once

#include <array>
#include <cstdint>

#include "core/volume.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess {

// Voxel index ranges [begin, end) along i, j, k.
struct IndexBox {
  std::array<std::int64_t, 3> begin{0, 0, 0};
  std::array<std::int64_t, 3> end{0, 0, 0};
  bool empty() const { return end[0] <= begin[0] || end[1] <= begin[1] || end[2] <= begin[2]; }
  core::VolumeSize size() const;  // zero along an empty axis
  bool operator==(const IndexBox&) const = default;
};

// An axis-aligned box in patient LPS millimetres; min ≤ max on every axis.
struct PatientBox {
  core::Vec3 min{0, 0, 0};
  core::Vec3 max{0, 0, 0};
};

struct TissueCropOptions {
  float threshold_hu = -400;  // tissue: voxels ≥ this (between air −1000 and fat −100)
  double margin_mm = 5;       // ≥ 0; added on every side, ceil(margin / spacing) voxels per axis
};

// The voxels whose centres lie in the box: the index range spanned by the box's corners mapped
// through the inverse of IndexToPatient (exact for an axis-aligned grid; for a rotated or
// sheared grid, the index-space bounding box of the patient box), clamped to the volume.
// Empty when the box misses the volume. Throws std::invalid_argument if min > max.
IndexBox index_box_of(const core::Volume& volume, const PatientBox& box);

// The smallest box holding every voxel ≥ threshold_hu; empty when there is none.
IndexBox tissue_bounding_box(const core::Volume& volume, float threshold_hu);

// Crops to the box clamped to the volume (a warning in the record when clamping changed it).
// Throws std::invalid_argument when the clamped box is empty.
StepResult crop(const core::Volume& volume, const IndexBox& box);

// crop(index_box_of(box)); throws std::invalid_argument when no voxel centre lies in the box.
StepResult crop_to_patient_box(const core::Volume& volume, const PatientBox& box);

// Crops to tissue_bounding_box plus the margin. When no voxel reaches the threshold, the volume
// is returned unchanged with a warning and the parameter tissue_found = "false".
StepResult crop_to_tissue(const core::Volume& volume, const TissueCropOptions& options = {});

}  // namespace typemerge::preprocess
