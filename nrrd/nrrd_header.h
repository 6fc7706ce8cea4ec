// parse_nrrd_header: the text header of a NRRD file → what reading its samples needs, its
// LPS geometry, and the segments of a 3D Slicer segmentation (.seg.nrrd).
//
// Fields read: type, dimension (3, or 4 with one non-spatial axis first or last: a list of
// layers), sizes, encoding (raw, gzip), endian, space (left-posterior-superior / LPS,
// right-anterior-superior / RAS, left-anterior-superior / LAS; scanner-xyz and
// 3D-right-handed taken as LPS with a warning), space directions (or spacings), space origin,
// kinds, data file, byte skip, line skip. Key/value pairs are read only for Slicer's
// SegmentN_Name, _Color, _LabelValue and _Layer; content, comments and every other key/value
// never leave this module (they can hold identifying free text).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/label_volume.h"
#include "core/volume.h"
#include "volume_file/sample_decoding.h"

namespace typemerge::nrrd {

class ReadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Encoding { raw, gzip };

struct NrrdHeader {
  core::VolumeSize size;          // the three spatial axes, in file order
  std::size_t layers = 1;         // entries of the non-spatial axis (1 when there is none)
  bool layer_axis_first = true;   // the non-spatial axis is the fastest (else the slowest)
  core::IndexToPatient geometry;  // index → LPS mm (centre of the first sample at origin)
  volume_file::SampleType type = volume_file::SampleType::uint8;
  bool big_endian = false;
  Encoding encoding = Encoding::raw;
  std::string data_file;       // detached data, relative to the header's folder; "" attached
  std::int64_t byte_skip = 0;  // -1: the data is the file's last bytes (raw only)
  std::int64_t line_skip = 0;
  std::size_t header_bytes = 0;         // attached data starts here (after the blank line)
  bool segmentation = false;            // it has Slicer's Segment keys (a .seg.nrrd)
  std::vector<core::Segment> segments;  // from the Segment keys, in their index order
  std::vector<std::string> warnings;

  std::uint64_t samples() const;     // voxels × layers
  std::uint64_t data_bytes() const;  // samples × sample bytes
};

// `text`: the file's start; the header ends at its first empty line (or at the end of `text`
// for a detached header). Throws ReadError.
NrrdHeader parse_nrrd_header(std::string_view text);

}  // namespace typemerge::nrrd
