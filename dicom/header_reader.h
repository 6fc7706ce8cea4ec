// Reads and validates the headers of one file with DCMTK, without loading its pixels.
//
// The result is either one SliceHeader per frame or the reason the file is skipped. Every
// check that can be made before touching pixel data is made here: value representations,
// finite decimal strings, image size bounds, the pixel byte count against the pixel data
// length and the file size. After this, the pixel reader may trust the header.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "dicom/slice_header.h"

namespace typemerge::dicom {

struct HeaderReadOptions {
  bool allow_non_ct_modality = false;  // accept MR/PT/... monochrome images as volume slices
  std::uint64_t max_pixel_bytes_per_file = std::uint64_t{4} << 30;
};

struct HeaderReadResult {
  FileKind kind = FileKind::not_dicom;
  std::vector<SliceHeader> frames;  // empty when the file is skipped
  std::string skip_reason;          // why the file is not a usable CT slice (empty if it is)
  // The file's Modality when that alone refused it (allow_non_ct_modality would accept it);
  // empty otherwise. Lets callers say "MR images, use --allow-non-ct" without parsing text.
  std::string refused_modality;
  std::vector<std::string> warnings;
};

// DCMTK's own log goes to stderr; the loader reports through its results instead.
void silence_dcmtk_log();

HeaderReadResult read_headers(const std::filesystem::path& file, const HeaderReadOptions& options);

}  // namespace typemerge::dicom
