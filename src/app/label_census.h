// label_census: the labels of one layer of a label map, each with its voxel count and index
// bounding box, found in one pass over the samples.
//
// Preconditions: every sample an integer in [0, 2^24] (checked by the caller: label mode
// refuses other maps). Label 0 is background and not counted. Memory: a dense table of
// (max label + 1) entries when the largest label is ≤ 65535, else a map of the labels present.
#pragma once

#include <array>
#include <cstdint>
#include <map>

#include "core/volume.h"

namespace typemerge::app {

struct LabelExtent {
  std::uint64_t voxels = 0;
  std::array<std::int64_t, 3> min{};  // index box, inclusive
  std::array<std::int64_t, 3> max{};
};

// Label → its extent, for every label > 0 present, in increasing label order.
std::map<std::int32_t, LabelExtent> label_census(const core::Volume& layer);

// The share of labelled voxels (> 0) whose next voxel along x, in the same row, holds the same
// label (a row's last voxel is not counted); 1 when none is counted. A label map's regions are
// mostly uniform, so most of its voxels count (Slicer's organ maps in the shared data: 0.99);
// grey values of an image read as labels change from voxel to voxel (a brain MR's: 0.05).
double label_coherence(const core::Volume& layer);

}  // namespace typemerge::app
