// read_nifti: a NIfTI-1 or NIfTI-2 single file (.nii, or .nii.gz) → a Volume of its values.
//
// Contract:
//  * values: the stored samples (every integer and float type NIfTI defines except complex and
//    RGB) times scl_slope plus scl_inter (slope 0 or non-finite: no scaling); non-finite values
//    are stored as 0 and counted in a warning. Storage: int16 when every value is an integer
//    within int16 (an integer type, slope 1, integer intercept: volume_file::fits_int16), as
//    a CT series loads; float otherwise. The values are the same either way.
//  * geometry: the sform when sform_code > 0, else the qform when qform_code > 0, else the pixel
//    spacing alone (a warning: orientation unknown); NIfTI's world is RAS, so x and y are negated
//    to give LPS (a rotation: handedness, and so surface winding, is kept). The origin is the
//    centre of voxel (0, 0, 0), as core::IndexToPatient wants.
//  * refused with ReadError (one line, naming no content of the file): a file that is not
//    NIfTI single-file, truncated or damaged gzip, vox_offset beyond the file, data shorter than
//    the header says, more than three dimensions of extent > 1 (4D: "one volume at a time"),
//    dimensions ≤ 0 or whose product overflows, a non-finite or singular affine, an unsupported
//    data type, a volume larger than ReadOptions::max_volume_bytes (checked from the header
//    before any data is read).
//  * privacy: descrip, aux_file, intent_name, db_name and extensions are never read into
//    anything this module returns.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/volume.h"
#include "volume_file/sample_decoding.h"

namespace typemerge::nifti {

class ReadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct NiftiHeader {
  int version = 1;  // 1 or 2
  core::VolumeSize size;
  core::IndexToPatient geometry;  // index → LPS mm
  std::string geometry_source;    // "sform", "qform" or "pixel spacing"
  volume_file::SampleType type = volume_file::SampleType::uint8;
  bool swap = false;  // the file's byte order is not this machine's
  double slope = 1, inter = 0;
  std::uint64_t data_offset = 0;  // vox_offset
  bool intent_label = false;      // intent_code NIFTI_INTENT_LABEL: values are labels
  std::vector<std::string> warnings;

  std::uint64_t data_bytes() const;  // size.voxels() × sample bytes (checked not to overflow)
};

// The header from the start of the (inflated) file; `bytes` may hold more. Throws ReadError.
NiftiHeader parse_header(std::span<const std::uint8_t> bytes);
// The header of a file, without reading its data. Throws ReadError.
NiftiHeader read_header(const std::filesystem::path& path);

struct NiftiImage {
  NiftiHeader header;
  core::Volume volume;
  volume_file::DecodeSummary values;
  std::vector<std::string> warnings;  // the header's, then the values'
};

struct ReadOptions {
  std::uint64_t max_volume_bytes = std::uint64_t{16} << 30;  // float samples, refused first
};

// The whole (inflated) file. Throws ReadError.
NiftiImage decode_nifti(std::span<const std::uint8_t> file_bytes, const ReadOptions& options = {});
// Reads (inflating .gz) no more than the header says the data needs. Throws ReadError.
NiftiImage read_nifti(const std::filesystem::path& path, const ReadOptions& options = {});

}  // namespace typemerge::nifti
