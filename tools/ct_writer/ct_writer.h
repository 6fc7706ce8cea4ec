// ct_writer: writes synthetic CT Image Storage files, for the shipped sample series and for tests.
//
// A CtSliceSpec holds every attribute as a plain value so that a test can break any one of
// them: geometry and rescale are strings ("NaN", "-1", "inf", a wrong number of values are all
// writable), the pixel module is raw integers, and `extra` / `omit` reach any other tag. The
// C++ type of a field follows the attribute's DICOM value representation: text VRs (UI, CS, DS,
// IS, LO, PN, DA, ...) are std::string and written verbatim, US attributes are std::uint16_t.
// Optional text attributes are std::optional: nullopt leaves the attribute out, "" writes it
// empty (a type 2 attribute present without a value).
//
// Output is deterministic: UIDs come from make_uid() over a seed string, no date or time comes
// from the clock, and the file meta header names this writer rather than the DCMTK version, so
// the same spec gives the same bytes on every run and machine (for a given zlib, for deflate).
//
// Nothing here exposes DCMTK: callers and tests link DCMTK themselves only to read files back.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace typemerge::ct_writer {

using Vec3 = std::array<double, 3>;

// Root of every UID this writer makes. A fixed root plus a hash of a seed string, never time or
// randomness, so that regenerated files are byte-identical.
inline constexpr std::string_view kUidRoot = "1.2.826.0.1.3680043.10.1234.";
inline constexpr std::string_view kCtImageStorage = "1.2.840.10008.5.1.4.1.1.2";
inline constexpr std::string_view kSecondaryCaptureImageStorage = "1.2.840.10008.5.1.4.1.1.7";
// Written as (0002,0012) / (0002,0013) instead of DCMTK's own, which change with its version.
inline constexpr std::string_view kImplementationClassUid = "1.2.826.0.1.3680043.10.1234.0.1";
inline constexpr std::string_view kImplementationVersionName = "TYPEMERGE_CTW_1";

enum class TransferSyntax {
  implicit_little,   // 1.2.840.10008.1.2
  explicit_little,   // 1.2.840.10008.1.2.1
  explicit_big,      // 1.2.840.10008.1.2.2 (retired, still met in archives)
  deflated_little,   // 1.2.840.10008.1.2.1.99
  jpeg_lossless,     // 1.2.840.10008.1.2.4.70, process 14 selection value 1
  jpeg_ls_lossless,  // 1.2.840.10008.1.2.4.80
  rle_lossless,      // 1.2.840.10008.1.2.5
};

const char* to_uid(TransferSyntax syntax);

// How the bytes around the data set look. Reading code meets all three in the wild.
enum class Container {
  part10,        // 128-byte preamble, "DICM", file meta header, data set (PS3.10)
  no_preamble,   // file meta header first (no preamble, no "DICM"), then the data set
  dataset_only,  // the bare data set in its transfer syntax, no meta header at all
};

struct Tag {
  std::uint16_t group = 0;
  std::uint16_t element = 0;
};

// A few tags tests commonly omit or override; any other tag can be given by number.
inline constexpr Tag kPixelDataTag{0x7FE0, 0x0010};
inline constexpr Tag kImagePositionPatientTag{0x0020, 0x0032};
inline constexpr Tag kImageOrientationPatientTag{0x0020, 0x0037};
inline constexpr Tag kPixelSpacingTag{0x0028, 0x0030};
inline constexpr Tag kRescaleInterceptTag{0x0028, 0x1052};
inline constexpr Tag kRescaleSlopeTag{0x0028, 0x1053};

// An attribute written with its data-dictionary VR from text (DCMTK putAndInsertString rules:
// multiple values separated by '\'); a private element the dictionary does not know is
// written as LO. Not for sequences.
struct TagValue {
  Tag tag;
  std::string value;
};

// One CT slice: every attribute this writer puts in the file. The defaults make a valid 16×16
// axial slice at the origin with 1 mm pixels, 12-bit unsigned, intercept −1024, all stored 0.
struct CtSliceSpec {
  // SOP common, study, series, frame of reference.
  std::string sop_class_uid{kCtImageStorage};
  std::string sop_instance_uid = "1.2.826.0.1.3680043.10.1234.1.1";
  std::string study_instance_uid = "1.2.826.0.1.3680043.10.1234.1.2";
  std::string series_instance_uid = "1.2.826.0.1.3680043.10.1234.1.3";
  std::string frame_of_reference_uid = "1.2.826.0.1.3680043.10.1234.1.4";
  std::string modality = "CT";
  std::string image_type = "ORIGINAL\\PRIMARY\\AXIAL";
  std::string series_description = "Synthetic CT";
  std::string series_number = "1";    // IS
  std::string instance_number = "1";  // IS
  std::string acquisition_number = "1";
  std::string patient_position = "HFS";
  std::string kvp = "120";  // DS
  std::string manufacturer = "typemerge ct_writer";
  std::optional<std::string> convolution_kernel;
  std::optional<std::string> gantry_detector_tilt;    // DS, degrees
  std::optional<std::string> slice_location;          // DS, mm
  std::optional<std::string> spacing_between_slices;  // DS, mm
  std::optional<std::string> specific_character_set;

  // Patient and study: obviously synthetic; tests put canary tokens here to check that
  // nothing identifying leaks into outputs or logs.
  std::string patient_name = "Synthetic^Phantom";
  std::string patient_id = "SYNTHETIC";
  std::string patient_birth_date = "19000101";
  std::string patient_sex = "O";
  std::string study_date = "20000101";
  std::string study_time = "000000";
  std::string study_id = "1";
  std::string accession_number;
  std::string referring_physician_name;
  std::string study_description = "Synthetic study";

  // Geometry (text, so tests can write anything). LPS mm.
  std::string image_position_patient = "0\\0\\0";
  std::string image_orientation_patient = "1\\0\\0\\0\\1\\0";
  std::string pixel_spacing = "1\\1";  // between rows \ between columns
  std::string slice_thickness = "1";

  // Image pixel module and rescale.
  std::uint16_t rows = 16;
  std::uint16_t columns = 16;
  std::uint16_t samples_per_pixel = 1;
  std::uint16_t bits_allocated = 16;
  std::uint16_t bits_stored = 12;
  std::uint16_t high_bit = 11;
  std::uint16_t pixel_representation = 0;  // 0 unsigned, 1 two's complement
  std::string photometric = "MONOCHROME2";
  std::string rescale_intercept = "-1024";  // DS
  std::string rescale_slope = "1";          // DS
  std::optional<std::string> rescale_type;  // e.g. "HU"
  std::optional<std::string> window_center;
  std::optional<std::string> window_width;
  // Written as US when pixel_representation is 0, else SS (its VR follows the pixel data).
  std::optional<std::int32_t> pixel_padding_value;

  // Stored values, row by row (column index fastest), as their 16-bit patterns: a signed value
  // v is static_cast<std::uint16_t>(static_cast<std::int16_t>(v)). Empty means rows × columns ×
  // samples zeros. The size is not checked against rows × columns, so a short or long PixelData
  // is writable. bits_allocated 8 writes the low byte of each value (OB); any other value
  // writes 16-bit words (OW), so a header claiming 32 bits gets a PixelData too short for it.
  std::vector<std::uint16_t> pixels;

  TransferSyntax transfer_syntax = TransferSyntax::explicit_little;
  Container container = Container::part10;

  // Applied in this order after the fields above: `extra` puts (and overrides) attributes,
  // `omit` removes them (kPixelDataTag drops the pixels), then the file is cut to
  // `truncate_to_bytes` if that is smaller than what was written. Both act on the data set
  // only: the file meta header (group 0002) is always built from sop_class_uid,
  // sop_instance_uid and transfer_syntax.
  std::vector<TagValue> extra;
  std::vector<Tag> omit;
  std::optional<std::uintmax_t> truncate_to_bytes;
};

// Writes one file, replacing `path`. Throws std::runtime_error naming the file and the
// attribute or step that failed (e.g. an encoder refusing inconsistent pixel attributes).
void write_ct_slice(const CtSliceSpec& spec, const std::filesystem::path& path);

// A regular stack of slices: slice k is at origin + k · slice_step, its rows and columns along
// the orientation's row and column directions.
struct SeriesLayout {
  std::string uid_seed = "ct_writer";  // all UIDs are make_uid(uid_seed + "/...")
  std::uint16_t columns = 16;
  std::uint16_t rows = 16;
  std::int32_t slices = 8;
  std::array<double, 2> pixel_spacing{1.0, 1.0};  // between rows, between columns (DICOM order), mm
  double slice_spacing = 1.0;                     // mm along the slice normal
  std::optional<double> slice_thickness;          // default slice_spacing
  Vec3 origin{0, 0, 0};                           // ImagePositionPatient of slice 0, LPS mm
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};  // row direction, column direction
  // Step between consecutive slice positions. Default: slice_spacing along row × column (the
  // normal). Set it off the normal to model a gantry-tilted (sheared) acquisition.
  std::optional<Vec3> slice_step;

  std::uint16_t bits_allocated = 16;
  std::uint16_t bits_stored = 12;
  std::uint16_t high_bit = 11;
  std::uint16_t pixel_representation = 0;
  double rescale_intercept = -1024;
  double rescale_slope = 1;

  // Voxel values, i along a row (column index), j down the columns (row index), k slice. If
  // `stored_value` is set it gives raw stored values (anything, including bits above
  // bits_stored); else `hu` gives Hounsfield units, converted with stored_from_hu; else every
  // stored value is 0.
  std::function<std::int32_t(int i, int j, int k)> stored_value;
  std::function<double(int i, int j, int k)> hu;

  std::string series_description = "Synthetic axial series";
  std::int32_t series_number = 1;
  TransferSyntax transfer_syntax = TransferSyntax::explicit_little;
};

// One spec per slice, in slice order (k = 0 first), instance numbers 1..slices, SliceLocation
// and SpacingBetweenSlices filled in like a scanner would. Edit the returned specs to break
// one slice.
std::vector<CtSliceSpec> make_axial_series(const SeriesLayout& layout);

// Writes specs into `directory` (created if missing) and returns the paths in spec order.
// Default names: slice_0000.dcm, slice_0001.dcm, ... by position in `specs`.
using FileNamer = std::function<std::string(std::size_t index, const CtSliceSpec& spec)>;
std::vector<std::filesystem::path> write_series(const std::vector<CtSliceSpec>& specs,
                                                const std::filesystem::path& directory,
                                                const FileNamer& name = {});

// HU → stored value: round((hu − intercept) / slope) to nearest (ties away from zero), clamped
// to what bits_stored holds for the pixel representation ([0, 2^b − 1] or [−2^(b−1), 2^(b−1)−1]).
std::int32_t stored_from_hu(double hu, double rescale_intercept, double rescale_slope,
                            std::uint16_t bits_stored, std::uint16_t pixel_representation);

// The 16-bit pattern PixelData holds for a stored value (two's complement for negatives).
inline std::uint16_t to_pixel_word(std::int32_t stored) {
  return static_cast<std::uint16_t>(static_cast<std::uint32_t>(stored) & 0xFFFFu);
}

// kUidRoot followed by a decimal 64-bit FNV-1a hash of `key`: valid (≤ 64 characters, no
// leading zeros), stable across runs and platforms, distinct for distinct keys in practice.
std::string make_uid(std::string_view key);

// 64-bit FNV-1a, exposed for deterministic file names and noise seeds.
std::uint64_t fnv1a64(std::string_view bytes);

// A decimal string (DS) for `value`: the shortest text that reads back to the same double if
// that fits DS's 16 characters, else fewer significant digits. Never "-0". Locale independent.
std::string format_ds(double value);
// Values joined with '\' (multi-valued DS such as ImagePositionPatient).
std::string format_ds(std::span<const double> values);

}  // namespace typemerge::ct_writer
