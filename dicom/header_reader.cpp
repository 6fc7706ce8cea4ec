#include "dicom/header_reader.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcitem.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcstack.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcxfer.h>

#include <dcmtk/oflog/oflog.h>

#include <algorithm>
#include <mutex>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <optional>

#include "dicom/decimal_string.h"
#include "dicom/nesting_prescan.h"

namespace typemerge::dicom {
namespace {

// Header values above this are read lazily; pixel data stays on disk during the scan.
constexpr Uint32 kLazyValueBytes = 4096;
constexpr std::uint32_t kMaxFramesPerFile = 16384;

const char* const kCtImageStorage = "1.2.840.10008.5.1.4.1.1.2";
const char* const kEnhancedCtImageStorage = "1.2.840.10008.5.1.4.1.1.2.1";
const char* const kMediaStorageDirectory = "1.2.840.10008.1.3.10";
const char* const kSecondaryCapturePrefix = "1.2.840.10008.5.1.4.1.1.7";

// A file that fails a check; the message is the skip reason.
struct Refusal {
  std::string message;
};

std::string trimmed(const OFString& value) {
  std::string text(value.c_str());
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  while (!text.empty() && text.front() == ' ') text.erase(text.begin());
  return text;
}

std::string get_text(DcmItem& item, const DcmTagKey& tag) {
  OFString value;
  if (item.findAndGetOFStringArray(tag, value).bad()) return {};
  return trimmed(value);
}

std::string upper(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return text;
}

// A US attribute read strictly: a wrong VR (possible in explicit-VR files) is a refusal,
// not a silent conversion.
std::optional<std::uint16_t> get_us(DcmItem& item, const DcmTagKey& tag, const char* name,
                                    bool required) {
  DcmElement* element = nullptr;
  if (item.findAndGetElement(tag, element).bad() || element == nullptr ||
      element->getLength() == 0) {
    if (required) throw Refusal{std::string("missing ") + name};
    return std::nullopt;
  }
  const DcmEVR vr = element->ident();
  if (vr != EVR_US) {
    throw Refusal{std::string(name) + " has value representation " + DcmVR(vr).getVRName() +
                  ", expected US"};
  }
  Uint16 value = 0;
  if (element->getUint16(value).bad()) throw Refusal{std::string("unreadable ") + name};
  return value;
}

// PixelPaddingValue and its range limit are US or SS depending on PixelRepresentation.
std::optional<std::int32_t> get_padding(DcmItem& item, const DcmTagKey& tag, bool is_signed) {
  DcmElement* element = nullptr;
  if (item.findAndGetElement(tag, element).bad() || element == nullptr ||
      element->getLength() < 2) {
    return std::nullopt;
  }
  Uint16 raw = 0;
  if (element->getUint16(raw).good()) {
    return is_signed ? static_cast<std::int32_t>(static_cast<std::int16_t>(raw)) : raw;
  }
  Sint16 value = 0;
  if (element->getSint16(value).good()) {
    return is_signed ? value : static_cast<std::int32_t>(static_cast<Uint16>(value));
  }
  return std::nullopt;
}

std::optional<std::vector<double>> get_decimals(DcmItem& item, const DcmTagKey& tag,
                                                std::size_t count, const char* name) {
  const std::string text = get_text(item, tag);
  if (text.empty()) return std::nullopt;
  auto values = parse_decimal_list(text, count);
  if (!values) {
    throw Refusal{std::string(name) + " '" + text.substr(0, 64) + "' is not " +
                  std::to_string(count) + " finite number" + (count > 1 ? "s" : "")};
  }
  return values;
}

// Geometry and rescale of one frame, from the classic attributes or a functional group item.
// Later calls override earlier ones, so shared groups are read first, then per-frame groups.
void read_geometry(DcmItem& item, SliceHeader& header) {
  if (auto v = get_decimals(item, DCM_ImagePositionPatient, 3, "ImagePositionPatient")) {
    header.position = Vec3{(*v)[0], (*v)[1], (*v)[2]};
  }
  if (auto v = get_decimals(item, DCM_ImageOrientationPatient, 6, "ImageOrientationPatient")) {
    header.orientation = std::array<double, 6>{(*v)[0], (*v)[1], (*v)[2],
                                               (*v)[3], (*v)[4], (*v)[5]};
  }
  if (auto v = get_decimals(item, DCM_PixelSpacing, 2, "PixelSpacing")) {
    if (!((*v)[0] > 0) || !((*v)[1] > 0)) {
      throw Refusal{"PixelSpacing " + std::to_string((*v)[0]) + "\\" + std::to_string((*v)[1]) +
                    " is not positive"};
    }
    header.pixel_spacing = std::array<double, 2>{(*v)[0], (*v)[1]};
  }
  if (auto v = get_decimals(item, DCM_SliceThickness, 1, "SliceThickness")) {
    header.slice_thickness = (*v)[0];
  }
  if (auto v = get_decimals(item, DCM_RescaleSlope, 1, "RescaleSlope")) {
    if ((*v)[0] == 0.0) throw Refusal{"RescaleSlope is 0"};
    header.rescale_slope = (*v)[0];
    header.has_rescale = true;
  }
  if (auto v = get_decimals(item, DCM_RescaleIntercept, 1, "RescaleIntercept")) {
    header.rescale_intercept = (*v)[0];
    header.has_rescale = true;
  }
}

// Reads the geometry held in one functional group item (shared or per frame).
void read_functional_group(DcmItem& group, SliceHeader& header) {
  static const DcmTagKey kSequences[] = {DCM_PlanePositionSequence, DCM_PlaneOrientationSequence,
                                         DCM_PixelMeasuresSequence,
                                         DCM_PixelValueTransformationSequence};
  for (const DcmTagKey& sequence : kSequences) {
    DcmItem* inner = nullptr;
    if (group.findAndGetSequenceItem(sequence, inner, 0).good() && inner != nullptr) {
      read_geometry(*inner, header);
    }
  }
}

// DCMTK reads values longer than kLazyValueBytes on first access and allocates their declared
// length before reading: a 1 kB file declaring a 2 GB name allocates 2 GB (found by
// fuzz/fuzz_dicom_file). No value is longer than the file holds, or for a deflated data set
// than 1032 times it (zlib's largest ratio), so a longer one refuses the file before any
// value is read. An undefined length belongs to sequences and encapsulated pixel data only:
// on a plain value (a 587-byte file with an SV element of undefined length) DCMTK took it as
// 4 GB and allocated that when the value was read as text (fuzz_dicom_file, oom-e93235e3…).
void check_value_lengths(DcmFileFormat& format, std::uint64_t file_bytes, bool deflated) {
  DcmStack stack;
  while (format.nextObject(stack, OFTrue).good()) {
    DcmObject* object = stack.top();
    if (object == nullptr || !object->isLeaf()) continue;
    const Uint32 length = object->getLengthField();
    const bool undefined = length == DCM_UndefinedLength;
    if (undefined ? object->getTag() == DCM_PixelData
                  : file_bytes == 0 || length <= (deflated ? file_bytes * 1032 + 1024 : file_bytes)) {
      continue;
    }
    char tag[16];
    std::snprintf(tag, sizeof tag, "(%04X,%04X)", unsigned{object->getGTag()},
                  unsigned{object->getETag()});
    if (undefined) {
      throw Refusal{std::string("damaged DICOM file: element ") + tag +
                    " has an undefined length, which only sequences and pixel data may have"};
    }
    throw Refusal{std::string("damaged DICOM file: element ") + tag + " declares " +
                  std::to_string(length) + " bytes, more than the " + std::to_string(file_bytes) +
                  "-byte file holds"};
  }
}

// Whether a file is DICOM at all, before any parsing: the DICM magic after the 128-byte
// preamble (PS3.10 §7.1), or, for data sets written without it (old ACR-NEMA style files,
// some exporters), a first element of the command, meta or identifying group (0000, 0002,
// 0008; little or big endian) followed by a valid VR (explicit) or by a length the file can
// hold (implicit). Text files (README, LICENSE, notes) start with letters: their first four
// bytes read as an element of a private group such as (2023,6173) "# ty", which DCMTK would
// report as a damaged data set; they are simply not DICOM.
bool starts_like_dicom(const std::filesystem::path& file, std::uint64_t file_bytes) {
  unsigned char head[132] = {};
  std::FILE* in = std::fopen(file.c_str(), "rb");
  if (in == nullptr) return true;  // let the reader report why it cannot open the file
  const std::size_t got = std::fread(head, 1, sizeof head, in);
  std::fclose(in);
  if (got >= 132 && std::memcmp(head + 128, "DICM", 4) == 0) return true;
  if (got < 8) return false;
  const unsigned little = head[0] | (head[1] << 8);
  const unsigned big = (head[0] << 8) | head[1];
  auto first_group = [](unsigned g) { return g == 0x0000 || g == 0x0002 || g == 0x0008; };
  if (!first_group(little) && !first_group(big)) return false;
  static constexpr const char* kVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL",
                                         "IS", "LO", "LT", "OB", "OD", "OF", "OL", "OV", "OW",
                                         "PN", "SH", "SL", "SQ", "SS", "ST", "SV", "TM", "UC",
                                         "UI", "UL", "UN", "UR", "US", "UT", "UV"};
  for (const char* vr : kVrs) {
    if (head[4] == static_cast<unsigned char>(vr[0]) &&
        head[5] == static_cast<unsigned char>(vr[1])) {
      return true;
    }
  }
  const std::uint64_t length_little = std::uint64_t{head[4]} | std::uint64_t{head[5]} << 8 |
                                      std::uint64_t{head[6]} << 16 | std::uint64_t{head[7]} << 24;
  const std::uint64_t length_big = std::uint64_t{head[7]} | std::uint64_t{head[6]} << 8 |
                                   std::uint64_t{head[5]} << 16 | std::uint64_t{head[4]} << 24;
  return (first_group(little) && length_little + 8 <= file_bytes) ||
         (first_group(big) && length_big + 8 <= file_bytes);
}

std::uint64_t file_size_or_zero(const std::filesystem::path& file) {
  std::error_code error;
  const auto size = std::filesystem::file_size(file, error);
  return error ? 0 : size;
}

// Fills `result` step by step; the kind set before a refusal is the file's classification.
void read_headers_or_throw(const std::filesystem::path& file, const HeaderReadOptions& options,
                           HeaderReadResult& result) {
  if (!starts_like_dicom(file, file_size_or_zero(file))) {
    result.kind = FileKind::not_dicom;
    throw Refusal{"not a DICOM file (no DICM magic, and it does not start with a DICOM element)"};
  }
  const NestingReport nesting = prescan_nesting(file);
  if (!nesting.error.empty()) {
    result.kind = FileKind::unreadable;
    throw Refusal{"refused before parsing: " + nesting.error};
  }

  // A cut-off file is the commonest damage (an interrupted copy); say so plainly.
  const std::uint64_t file_bytes = file_size_or_zero(file);
  if (nesting.pixel_data_offset && nesting.pixel_data_length != 0xFFFFFFFFu &&
      *nesting.pixel_data_offset + std::uint64_t{nesting.pixel_data_length} > file_bytes) {
    result.kind = FileKind::unreadable;
    throw Refusal{"truncated file: pixel data ends at byte " +
                  std::to_string(*nesting.pixel_data_offset + nesting.pixel_data_length) +
                  " of a " + std::to_string(file_bytes) + "-byte file"};
  }

  DcmFileFormat format;
  const OFCondition loaded =
      format.loadFile(OFFilename(file.c_str()), EXS_Unknown, EGL_noChange, kLazyValueBytes,
                      ERM_autoDetect);
  try {
    check_value_lengths(format, file_bytes, nesting.deflated);
  } catch (const Refusal&) {
    result.kind = FileKind::unreadable;
    throw;
  }
  DcmDataset& dataset = *format.getDataset();
  SliceHeader header;
  header.path = file;
  header.sop_class_uid = get_text(dataset, DCM_SOPClassUID);
  std::string media_class = get_text(*format.getMetaInfo(), DCM_MediaStorageSOPClassUID);
  if (loaded.bad()) {
    const bool has_preamble_or_meta = !media_class.empty() || !header.sop_class_uid.empty() ||
                                      format.getMetaInfo()->card() > 0;
    result.kind = has_preamble_or_meta ? FileKind::unreadable : FileKind::not_dicom;
    throw Refusal{result.kind == FileKind::not_dicom
                      ? std::string("not a DICOM file")
                      : std::string("damaged DICOM file: ") + loaded.text()};
  }
  if (media_class == kMediaStorageDirectory) {
    result.kind = FileKind::non_image;
    throw Refusal{"DICOMDIR (media directory)"};
  }
  DcmElement* pixel_data = nullptr;
  const bool has_pixels =
      dataset.findAndGetElement(DCM_PixelData, pixel_data).good() && pixel_data != nullptr;
  header.modality = upper(get_text(dataset, DCM_Modality));
  if (header.sop_class_uid.empty() && header.modality.empty() && !has_pixels) {
    result.kind = FileKind::not_dicom;
    throw Refusal{"not a DICOM file (no SOP class, modality or pixel data)"};
  }
  if (!has_pixels) {
    result.kind = FileKind::non_image;
    throw Refusal{"no pixel data (" + (header.modality.empty() ? std::string("no modality")
                                                               : header.modality) + ")"};
  }

  header.transfer_syntax_uid = DcmXfer(dataset.getOriginalXfer()).getXferID();
  header.sop_instance_uid = get_text(dataset, DCM_SOPInstanceUID);
  header.study_uid = get_text(dataset, DCM_StudyInstanceUID);
  header.series_uid = get_text(dataset, DCM_SeriesInstanceUID);
  header.frame_of_reference_uid = get_text(dataset, DCM_FrameOfReferenceUID);
  header.image_type = upper(get_text(dataset, DCM_ImageType));
  header.series_description = get_text(dataset, DCM_SeriesDescription);
  header.convolution_kernel = get_text(dataset, DCM_ConvolutionKernel);
  header.photometric = upper(get_text(dataset, DCM_PhotometricInterpretation));
  if (auto number = parse_integer(get_text(dataset, DCM_SeriesNumber))) {
    header.series_number = static_cast<std::int32_t>(std::clamp<long long>(*number, -1, 1 << 30));
  }

  const bool secondary_capture = header.sop_class_uid.rfind(kSecondaryCapturePrefix, 0) == 0;
  const bool ct_class = header.sop_class_uid == kCtImageStorage ||
                        header.sop_class_uid == kEnhancedCtImageStorage;
  result.kind = FileKind::other_image;
  if (secondary_capture) throw Refusal{"secondary capture image"};
  if (!ct_class && header.modality != "CT" && !options.allow_non_ct_modality) {
    result.refused_modality = header.modality.empty() ? "(none)" : header.modality;
    throw Refusal{"modality " + (header.modality.empty() ? std::string("(none)") : header.modality) +
                  ", not CT"};
  }

  header.rows = *get_us(dataset, DCM_Rows, "Rows", true);
  header.columns = *get_us(dataset, DCM_Columns, "Columns", true);
  header.samples_per_pixel = get_us(dataset, DCM_SamplesPerPixel, "SamplesPerPixel", false)
                                 .value_or(1);
  header.bits_allocated = *get_us(dataset, DCM_BitsAllocated, "BitsAllocated", true);
  header.bits_stored = get_us(dataset, DCM_BitsStored, "BitsStored", false)
                           .value_or(header.bits_allocated);
  header.high_bit = get_us(dataset, DCM_HighBit, "HighBit", false)
                        .value_or(static_cast<std::uint16_t>(header.bits_stored - 1));
  header.pixel_representation =
      get_us(dataset, DCM_PixelRepresentation, "PixelRepresentation", false).value_or(0);

  if (header.samples_per_pixel != 1 ||
      (header.photometric != "MONOCHROME2" && header.photometric != "MONOCHROME1")) {
    throw Refusal{"colour image (" + std::to_string(header.samples_per_pixel) + " samples, " +
                  (header.photometric.empty() ? std::string("no photometric interpretation")
                                              : header.photometric) + ")"};
  }
  result.kind = FileKind::ct_image;
  if (header.rows == 0 || header.columns == 0) throw Refusal{"image has zero rows or columns"};
  if (header.bits_allocated != 8 && header.bits_allocated != 16) {
    throw Refusal{"BitsAllocated " + std::to_string(header.bits_allocated) +
                  " is not supported (8 or 16)"};
  }
  if (header.bits_stored == 0 || header.bits_stored > header.bits_allocated ||
      header.high_bit + 1 < header.bits_stored || header.high_bit >= header.bits_allocated) {
    throw Refusal{"inconsistent BitsStored " + std::to_string(header.bits_stored) + " / HighBit " +
                  std::to_string(header.high_bit) + " / BitsAllocated " +
                  std::to_string(header.bits_allocated)};
  }
  if (header.pixel_representation > 1) {
    throw Refusal{"PixelRepresentation " + std::to_string(header.pixel_representation) +
                  " is not 0 or 1"};
  }
  const bool is_signed = header.pixel_representation == 1;
  header.pixel_padding_value = get_padding(dataset, DCM_PixelPaddingValue, is_signed);
  header.pixel_padding_range_limit = get_padding(dataset, DCM_PixelPaddingRangeLimit, is_signed);

  std::uint32_t frames = 1;
  const std::string frames_text = get_text(dataset, DCM_NumberOfFrames);
  if (!frames_text.empty()) {
    const auto parsed = parse_integer(frames_text);
    if (!parsed || *parsed < 1 || *parsed > kMaxFramesPerFile) {
      throw Refusal{"NumberOfFrames '" + frames_text.substr(0, 32) + "' is out of range"};
    }
    frames = static_cast<std::uint32_t>(*parsed);
  }
  header.frames_in_file = frames;

  // The byte count is computed in 64 bits and checked before anything is allocated.
  const std::uint64_t expected_bytes = std::uint64_t{header.rows} * header.columns * frames *
                                       (header.bits_allocated / 8u);
  if (expected_bytes > options.max_pixel_bytes_per_file) {
    throw Refusal{"image of " + std::to_string(header.columns) + "x" +
                  std::to_string(header.rows) + "x" + std::to_string(frames) +
                  " exceeds the per-file memory limit"};
  }
  const DcmXfer xfer(dataset.getOriginalXfer());
  const Uint32 pixel_length = pixel_data->getLength();
  if (!xfer.isEncapsulated()) {
    if (pixel_length < expected_bytes) {
      throw Refusal{"pixel data is " + std::to_string(pixel_length) + " bytes, expected " +
                    std::to_string(expected_bytes)};
    }
  }

  read_geometry(dataset, header);
  DcmItem* shared = nullptr;
  if (dataset.findAndGetSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0).good() &&
      shared != nullptr) {
    read_functional_group(*shared, header);
  }
  DcmSequenceOfItems* per_frame = nullptr;
  const bool has_per_frame =
      dataset.findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, per_frame).good() &&
      per_frame != nullptr;
  if (frames > 1 && (!has_per_frame || per_frame->card() != frames)) {
    throw Refusal{"multi-frame image (" + std::to_string(frames) +
                  " frames) without one per-frame functional group per frame"};
  }
  for (std::uint32_t frame = 0; frame < frames; ++frame) {
    SliceHeader frame_header = header;
    frame_header.frame = frame;
    if (has_per_frame && frame < per_frame->card()) {
      read_functional_group(*per_frame->getItem(frame), frame_header);
    }
    if (!frame_header.position) throw Refusal{"missing ImagePositionPatient"};
    if (!frame_header.orientation) throw Refusal{"missing ImageOrientationPatient"};
    if (!frame_header.pixel_spacing) throw Refusal{"missing PixelSpacing"};
    result.frames.push_back(std::move(frame_header));
  }
  if (header.modality != "CT") {
    result.warnings.push_back("modality " + header.modality + " accepted by explicit override");
  }
}

}  // namespace

void silence_dcmtk_log() {
  // DCMTK logs parse problems to stderr; they reach the user as skip reasons instead.
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::FATAL_LOG_LEVEL); });
}

HeaderReadResult read_headers(const std::filesystem::path& file,
                              const HeaderReadOptions& options) {
  silence_dcmtk_log();
  HeaderReadResult result;
  try {
    read_headers_or_throw(file, options, result);
    return result;
  } catch (const Refusal& refusal) {
    result.skip_reason = refusal.message;
  } catch (const std::bad_alloc&) {
    result.skip_reason = "out of memory while reading the header";
  } catch (const std::exception& error) {
    result.skip_reason = std::string("unexpected error: ") + error.what();
  }
  result.frames.clear();
  return result;
}

}  // namespace typemerge::dicom
