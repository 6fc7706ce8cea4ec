// LabelVolume: a segmentation on a patient grid — integer labels in one or more layers, and
// each segment's label, layer, name and colour as its file gives them.
//
// Every reader of segmentations (NIfTI/NRRD label maps, 3D Slicer .seg.nrrd, DICOM SEG) makes
// one of these; label mode extracts one closed surface per segment from it. Segments overlap
// only across layers (a voxel holds one label per layer): a reader packs overlapping segments
// (DICOM SEG, Slicer's layered segmentations) into separate layers.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/volume.h"

namespace typemerge::core {

struct Segment {
  std::int32_t label = 0;  // its value in its layer; > 0 (0 is background)
  std::size_t layer = 0;   // index into LabelVolume::layers
  std::string name;        // as the file names it (a structure's name, never a patient's); may be empty
  std::optional<std::array<std::uint8_t, 3>> srgb;  // display colour as the file gives it
};

struct LabelVolume {
  // All of one size and geometry; every sample an integer (exact in float up to 2^24).
  std::vector<Volume> layers;
  std::vector<Segment> segments;  // in the file's order; (layer, label) unique
};

}  // namespace typemerge::core
