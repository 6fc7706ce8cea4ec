// SliceHeader: what the loader needs to know about one image frame, as plain values.
//
// One DICOM file gives one header per frame (classic CT: one; Enhanced CT: one per frame with
// its own position and rescale from the functional groups). Nothing here refers to DCMTK, so
// grouping, sorting and geometry are testable and fuzzable on made-up headers.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace typemerge::dicom {

using Vec3 = std::array<double, 3>;

enum class FileKind {
  ct_image,     // CT Image Storage or Enhanced CT, or modality CT with pixels
  other_image,  // pixels, but not a CT slice: secondary capture, MR, colour, ...
  non_image,    // DICOM without pixels: SR, RTSTRUCT, DICOMDIR, presentation state, ...
  not_dicom,
  unreadable,   // DICOM that cannot be parsed safely: damaged, truncated, hostile nesting
};

const char* to_string(FileKind kind);

struct SliceHeader {
  std::filesystem::path path;
  FileKind kind = FileKind::not_dicom;
  std::uint32_t frame = 0;   // frame index inside the file
  std::uint32_t frames_in_file = 1;

  std::string sop_class_uid;
  std::string sop_instance_uid;
  std::string study_uid;
  std::string series_uid;
  std::string frame_of_reference_uid;
  std::string modality;
  std::string image_type;  // backslash-separated, upper case
  std::string series_description;
  std::string convolution_kernel;
  std::string transfer_syntax_uid;
  std::string photometric;
  std::int32_t series_number = 0;

  std::uint16_t rows = 0;
  std::uint16_t columns = 0;
  std::uint16_t samples_per_pixel = 1;
  std::uint16_t bits_allocated = 0;
  std::uint16_t bits_stored = 0;
  std::uint16_t high_bit = 0;
  std::uint16_t pixel_representation = 0;  // 0 unsigned, 1 two's complement
  std::optional<std::int32_t> pixel_padding_value;
  std::optional<std::int32_t> pixel_padding_range_limit;

  // Geometry in patient LPS mm. Absent values stay nullopt: the caller decides what is fatal.
  std::optional<Vec3> position;                    // ImagePositionPatient
  std::optional<std::array<double, 6>> orientation;  // ImageOrientationPatient: row dir, column dir
  std::optional<std::array<double, 2>> pixel_spacing;  // spacing between rows, between columns
  std::optional<double> slice_thickness;

  double rescale_slope = 1.0;
  double rescale_intercept = 0.0;
  bool has_rescale = false;

  bool is_localizer() const;
};

}  // namespace typemerge::dicom
