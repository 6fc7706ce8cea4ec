// `typemerge info FILE` for a NIfTI or NRRD file: its format, grid and LPS geometry, value
// range, and, for a segmentation or a label map, every label: number, name, voxel count,
// volume (mL) and bounding box (mm, LPS: the outer faces of its voxels).
//
// A file lists labels when it says it is a segmentation (Slicer segments, NIfTI intent
// "label"), or when its values are integers from 0 with at most 1,000 distinct labels (a CT
// in HU has negative values; a grey MR more distinct values).
#pragma once

#include <iosfwd>

#include "app/info_command.h"
#include "app/input_kind.h"

namespace typemerge::app {

int run_volume_file_info(const InfoOptions& options, InputKind kind, std::ostream& out);

}  // namespace typemerge::app
