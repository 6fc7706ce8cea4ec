// read_nrrd: a NRRD file (.nrrd with attached data, or a .nhdr header and its data file; raw
// or gzip) → one Volume per layer, in the file's units, with LPS geometry; and the segments of
// a 3D Slicer .seg.nrrd.
//
// Contract:
//  * layers: a 3D file gives one; a 4D file with a list axis (Slicer's layered segmentations:
//    list axis first) gives one per entry, all on the same grid.
//  * values: the stored samples of every integer and float type, in either byte order;
//    non-finite values are stored as 0 and counted in a warning. Storage, per layer: int16 when
//    every value is an integer within int16 (volume_file::fits_int16), float otherwise.
//  * refused with ReadError (one line, naming no content of the file): not NRRD, a truncated
//    header or data, damaged gzip, unsupported encodings (ascii, hex, bzip2), several data
//    files, sizes whose product overflows, singular or non-finite directions, a volume larger
//    than ReadOptions::max_volume_bytes (checked from the header before any data is read).
//  * privacy: see nrrd_header.h — only geometry, samples and segment names and colours leave.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "core/label_volume.h"
#include "core/volume.h"
#include "nrrd/nrrd_header.h"
#include "volume_file/sample_decoding.h"

namespace typemerge::nrrd {

struct NrrdImage {
  NrrdHeader header;
  std::vector<core::Volume> layers;   // header.layers of them
  volume_file::DecodeSummary values;  // over all layers
  std::vector<std::string> warnings;  // the header's, then the values'
};

struct ReadOptions {
  std::uint64_t max_volume_bytes = std::uint64_t{16} << 30;  // float samples of all layers
};

// The header of a file (reading at most its first 4 MiB). Throws ReadError.
NrrdHeader read_nrrd_header(const std::filesystem::path& path);
// The file; a detached data file is found beside the header. Throws ReadError.
NrrdImage read_nrrd(const std::filesystem::path& path, const ReadOptions& options = {});

// The samples of `data` (the data file's bytes, or the attached file's bytes after
// header.header_bytes) as the header lays them out. Throws ReadError.
NrrdImage decode_nrrd_data(NrrdHeader header, std::span<const std::uint8_t> data,
                           const ReadOptions& options = {});
// A whole attached .nrrd held in memory (what the fuzz target feeds). Throws ReadError.
NrrdImage decode_nrrd(std::span<const std::uint8_t> file_bytes, const ReadOptions& options = {});

// The segmentation a .seg.nrrd describes (its Segment keys), or, for a label map, one layer
// without segments (the caller finds the labels). Layers move out of `image`.
core::LabelVolume to_label_volume(NrrdImage&& image);

}  // namespace typemerge::nrrd
