// read_seg: a DICOM Segmentation (SEG) file → a core::LabelVolume on its frames' grid.
//
// What is read (DCMTK's dcmseg and dcmfg for the segments and functional groups):
// - Binary and fractional SEGs; a fractional voxel is inside when its value is at least half
//   the Maximum Fractional Value.
// - The grid: Plane Orientation, Pixel Measures and each frame's Plane Position from the
//   shared or per-frame functional groups. Frames are placed by their position along the slice
//   normal, in any order, with empty frames possibly left out (see frame_grid.h); frames that
//   fit no grid, are not stacked along the normal, or disagree on orientation are refused.
// - Binary frames are unpacked from the one continuous bit stream DICOM defines (frame f's
//   pixel p is bit f·rows·columns + p, least significant bit first); DCMTK 3.6.7's own frame
//   split is not used, as it is wrong when rows·columns is not a multiple of 8.
// - Segments: number, Segment Label (the structure's name) and Recommended Display CIELab
//   Value as sRGB (cielab.h). Overlapping segments are packed into layers: in file order,
//   each goes to the first layer where it overlaps no segment already there; its label in the
//   layer is its segment number.
// Refused, with the reason: Label Map SEG (a SOP class newer than DCMTK 3.6.7), JPEG 2000 and
// other compressed pixel data it does not decode (native, deflated and RLE are read), a pixel
// data shorter than its frames, sizes beyond the limits below, files nested deeper than
// dicom::kMaxSequenceDepth.
//
// Privacy: only structure names (Segment Label) leave the reader; patient, study and
// content-creator attributes are never read into its results, and messages name no file.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/label_volume.h"
#include "core/volume.h"

namespace typemerge::seg {

class SegError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr std::int64_t kMaxSlices = 65536;

enum class SegKind { binary, fractional };

struct SegSegmentInfo {
  std::uint16_t number = 0;  // Segment Number, > 0
  std::string name;          // Segment Label; may be empty
  std::optional<std::array<std::uint8_t, 3>> srgb;
};

// Everything but the pixels: what `info` lists and the memory estimate needs.
struct SegHeader {
  core::VolumeSize size;          // the frames' grid
  core::IndexToPatient geometry;  // index → LPS mm
  SegKind kind = SegKind::binary;
  std::uint16_t max_fractional_value = 1;  // fractional only
  std::vector<SegSegmentInfo> segments;    // in the file's order
  std::vector<std::uint16_t> frame_segment;  // per frame, its segment number
  std::vector<std::int64_t> frame_slice;     // per frame, its slice index on the grid
  std::vector<std::string> warnings;

  // Bytes of one layer of float labels; the label volume holds 1 to segments.size() layers.
  std::uint64_t layer_bytes() const {
    return static_cast<std::uint64_t>(size.voxels()) * sizeof(float);
  }
};

struct SegReadOptions {
  std::uint64_t max_volume_bytes = std::uint64_t{16} << 30;  // all layers together
};

struct SegVolume {
  core::LabelVolume labels;
  std::vector<std::string> warnings;
};

// Whether the file is a DICOM Segmentation (its SOP class, from the file's meta header or
// data set), without reading further. Never throws.
bool is_seg_file(const std::filesystem::path& file);

// The header, geometry and segments, without decoding a frame. Throws SegError.
SegHeader read_seg_header(const std::filesystem::path& file);

// Throws SegError with a one-line reason (no file name in it).
SegVolume read_seg(const std::filesystem::path& file, const SegReadOptions& options = {});

}  // namespace typemerge::seg
