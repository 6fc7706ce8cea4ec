// A NIfTI or NRRD input as the commands read it: its shape from the header alone (for the
// memory estimate, before any data is read), then its layers and segments.
//
// Privacy: nothing of the file's free text (NIfTI descrip, aux_file, intent_name, db_name,
// extensions; NRRD content, comments, key/values) reaches these structs — the readers drop it —
// except the segment names and colours of a .seg.nrrd. Messages never name the file.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "app/input_kind.h"
#include "core/label_volume.h"
#include "volume_file/sample_decoding.h"

namespace typemerge::app {

struct VolumeFileShape {
  std::string format;  // "NIfTI-1", "NIfTI-2", "NRRD"
  core::VolumeSize size;
  std::size_t layers = 1;
  core::IndexToPatient geometry;
  bool segmentation = false;  // the file says it holds labels (Slicer segments, NIfTI intent)
  volume_file::SampleType type = volume_file::SampleType::float32;
  // Its samples load as int16, as the header alone tells (volume_file::int16_by_type: an
  // integer type whose every value, scaled, fits); false where the data decides, or they do not.
  bool int16_samples = false;

  std::array<double, 3> spacing_mm() const {
    return {geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)};
  }
};

struct VolumeFile {
  VolumeFileShape shape;
  core::LabelVolume content;  // its layers (one for a 3D file) and the file's segments
  volume_file::DecodeSummary values;
  std::vector<std::string> warnings;
};

// Throw CommandError (input refused) with the reader's one-line reason.
VolumeFileShape read_volume_file_shape(const std::filesystem::path& path, InputKind kind);
VolumeFile read_volume_file(const std::filesystem::path& path, InputKind kind,
                            std::uint64_t max_volume_bytes = std::uint64_t{16} << 30);

}  // namespace typemerge::app
