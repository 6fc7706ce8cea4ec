// ct_writer: builds a DCMTK data set from a CtSliceSpec, encodes it and writes the file.
//
// Steps of write_ct_slice: put the attributes → put the pixels → apply `extra` and `omit` →
// compress if asked → let DCMTK encode the data set → wrap it in the container (preamble, a meta
// header we encode ourselves) → truncate. Every DCMTK status is checked and becomes a
// std::runtime_error that names the file and the step.
#include "ct_writer/ct_writer.h"

#include <dcmtk/config/osconfig.h>  // must come before any other DCMTK header
#include <dcmtk/dcmdata/dcdatset.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcrleerg.h>
#include <dcmtk/dcmdata/dcrlerp.h>
#include <dcmtk/dcmdata/dcvrss.h>
#include <dcmtk/dcmdata/dcvrus.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmjpeg/djencode.h>
#include <dcmtk/dcmjpeg/djrplol.h>
#include <dcmtk/dcmjpls/djencode.h>
#include <dcmtk/dcmjpls/djrparam.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace typemerge::ct_writer {

namespace {

std::string tag_text(const DcmTagKey& key) {
  char text[16];
  std::snprintf(text, sizeof text, "(%04X,%04X)", key.getGroup(), key.getElement());
  return text;
}

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what) {
  throw std::runtime_error("ct_writer: " + path.string() + ": " + what);
}

void check(const OFCondition& status, const std::filesystem::path& path, const std::string& what) {
  if (status.bad()) fail(path, what + ": " + status.text());
}

E_TransferSyntax to_dcmtk(TransferSyntax syntax) {
  switch (syntax) {
    case TransferSyntax::implicit_little:
      return EXS_LittleEndianImplicit;
    case TransferSyntax::explicit_little:
      return EXS_LittleEndianExplicit;
    case TransferSyntax::explicit_big:
      return EXS_BigEndianExplicit;
    case TransferSyntax::deflated_little:
      return EXS_DeflatedLittleEndianExplicit;
    case TransferSyntax::jpeg_lossless:
      return EXS_JPEGProcess14SV1;
    case TransferSyntax::jpeg_ls_lossless:
      return EXS_JPEGLSLossless;
    case TransferSyntax::rle_lossless:
      return EXS_RLELossless;
  }
  return EXS_Unknown;
}

bool is_encapsulated(TransferSyntax syntax) {
  return syntax == TransferSyntax::jpeg_lossless || syntax == TransferSyntax::jpeg_ls_lossless ||
         syntax == TransferSyntax::rle_lossless;
}

// DCMTK keeps its codecs in a process-wide registry. Encoders only (decoding is the loader's
// business); registered once, never deregistered, so concurrent writers are safe. The JPEG
// encoders are told never to mint a new SOP Instance UID, which would break determinism, and
// JPEG-LS encodes the stored values as they are ("raw"), not through DCMTK's image module.
void register_encoders() {
  static std::once_flag once;
  std::call_once(once, [] {
    DJEncoderRegistration::registerCodecs(ECC_lossyYCbCr, EUC_never);
    DJLSEncoderRegistration::registerCodecs(0, 0, 0, 0, /*preferCookedEncoding=*/OFFalse, 0, OFTrue,
                                            EJLSUC_never);
    DcmRLEEncoderRegistration::registerCodecs(OFFalse);
  });
}

void put_string(DcmItem& item, const DcmTagKey& key, const std::string& value,
                const std::filesystem::path& path) {
  DcmTag tag(key);
  // Private elements have no dictionary VR; write them as LO (what scanners mostly use).
  if (key.isPrivate() && tag.getEVR() == EVR_UNKNOWN) tag.setVR(DcmVR(EVR_LO));
  check(item.putAndInsertString(tag, value.c_str(), static_cast<Uint32>(value.size())),
        path, "cannot put " + tag_text(key));
}

void put_optional(DcmItem& item, const DcmTagKey& key, const std::optional<std::string>& value,
                  const std::filesystem::path& path) {
  if (value) put_string(item, key, *value, path);
}

void put_uint16(DcmItem& item, const DcmTagKey& key, std::uint16_t value,
                const std::filesystem::path& path) {
  check(item.putAndInsertUint16(DcmTag(key), value), path, "cannot put " + tag_text(key));
}

void put_attributes(const CtSliceSpec& spec, DcmItem& ds, const std::filesystem::path& path) {
  put_optional(ds, DCM_SpecificCharacterSet, spec.specific_character_set, path);
  put_string(ds, DCM_ImageType, spec.image_type, path);
  put_string(ds, DCM_SOPClassUID, spec.sop_class_uid, path);
  put_string(ds, DCM_SOPInstanceUID, spec.sop_instance_uid, path);
  put_string(ds, DCM_StudyDate, spec.study_date, path);
  put_string(ds, DCM_StudyTime, spec.study_time, path);
  put_string(ds, DCM_AccessionNumber, spec.accession_number, path);
  put_string(ds, DCM_Modality, spec.modality, path);
  put_string(ds, DCM_Manufacturer, spec.manufacturer, path);
  put_string(ds, DCM_ReferringPhysicianName, spec.referring_physician_name, path);
  put_string(ds, DCM_StudyDescription, spec.study_description, path);
  put_string(ds, DCM_SeriesDescription, spec.series_description, path);
  put_string(ds, DCM_PatientName, spec.patient_name, path);
  put_string(ds, DCM_PatientID, spec.patient_id, path);
  put_string(ds, DCM_PatientBirthDate, spec.patient_birth_date, path);
  put_string(ds, DCM_PatientSex, spec.patient_sex, path);
  put_string(ds, DCM_SliceThickness, spec.slice_thickness, path);
  put_string(ds, DCM_KVP, spec.kvp, path);
  put_optional(ds, DCM_SpacingBetweenSlices, spec.spacing_between_slices, path);
  put_optional(ds, DCM_GantryDetectorTilt, spec.gantry_detector_tilt, path);
  put_optional(ds, DCM_ConvolutionKernel, spec.convolution_kernel, path);
  put_string(ds, DCM_PatientPosition, spec.patient_position, path);
  put_string(ds, DCM_StudyInstanceUID, spec.study_instance_uid, path);
  put_string(ds, DCM_SeriesInstanceUID, spec.series_instance_uid, path);
  put_string(ds, DCM_StudyID, spec.study_id, path);
  put_string(ds, DCM_SeriesNumber, spec.series_number, path);
  put_string(ds, DCM_AcquisitionNumber, spec.acquisition_number, path);
  put_string(ds, DCM_InstanceNumber, spec.instance_number, path);
  put_string(ds, DCM_ImagePositionPatient, spec.image_position_patient, path);
  put_string(ds, DCM_ImageOrientationPatient, spec.image_orientation_patient, path);
  put_string(ds, DCM_FrameOfReferenceUID, spec.frame_of_reference_uid, path);
  put_optional(ds, DCM_SliceLocation, spec.slice_location, path);
  put_uint16(ds, DCM_SamplesPerPixel, spec.samples_per_pixel, path);
  put_string(ds, DCM_PhotometricInterpretation, spec.photometric, path);
  put_uint16(ds, DCM_Rows, spec.rows, path);
  put_uint16(ds, DCM_Columns, spec.columns, path);
  put_string(ds, DCM_PixelSpacing, spec.pixel_spacing, path);
  put_uint16(ds, DCM_BitsAllocated, spec.bits_allocated, path);
  put_uint16(ds, DCM_BitsStored, spec.bits_stored, path);
  put_uint16(ds, DCM_HighBit, spec.high_bit, path);
  put_uint16(ds, DCM_PixelRepresentation, spec.pixel_representation, path);
  put_optional(ds, DCM_WindowCenter, spec.window_center, path);
  put_optional(ds, DCM_WindowWidth, spec.window_width, path);
  put_string(ds, DCM_RescaleIntercept, spec.rescale_intercept, path);
  put_string(ds, DCM_RescaleSlope, spec.rescale_slope, path);
  put_optional(ds, DCM_RescaleType, spec.rescale_type, path);

  if (spec.pixel_padding_value) {
    // The dictionary VR is "US or SS"; the standard ties it to PixelRepresentation, and a
    // reader that trusts the VR would otherwise see −2000 as 63536.
    const std::int32_t v = *spec.pixel_padding_value;
    std::unique_ptr<DcmElement> element;
    if (spec.pixel_representation == 0) {
      element = std::make_unique<DcmUnsignedShort>(DcmTag(DCM_PixelPaddingValue, EVR_US));
      check(element->putUint16(static_cast<Uint16>(v)), path, "cannot put PixelPaddingValue");
    } else {
      element = std::make_unique<DcmSignedShort>(DcmTag(DCM_PixelPaddingValue, EVR_SS));
      check(element->putSint16(static_cast<Sint16>(v)), path, "cannot put PixelPaddingValue");
    }
    check(ds.insert(element.get(), /*replaceOld=*/OFTrue), path, "cannot insert PixelPaddingValue");
    element.release();  // owned by the data set now
  }
}

void put_pixels(const CtSliceSpec& spec, DcmItem& ds, const std::filesystem::path& path) {
  std::vector<std::uint16_t> zeros;
  const std::vector<std::uint16_t>* words = &spec.pixels;
  if (spec.pixels.empty()) {
    zeros.assign(std::size_t{spec.rows} * spec.columns * spec.samples_per_pixel, 0);
    words = &zeros;
  }
  if (spec.bits_allocated == 8) {
    std::vector<Uint8> bytes(words->size());
    std::transform(words->begin(), words->end(), bytes.begin(),
                   [](std::uint16_t w) { return static_cast<Uint8>(w & 0xFFu); });
    check(ds.putAndInsertUint8Array(DCM_PixelData, bytes.data(),
                                    static_cast<unsigned long>(bytes.size())),
          path, "cannot put PixelData");
  } else {
    check(ds.putAndInsertUint16Array(DCM_PixelData, words->data(),
                                     static_cast<unsigned long>(words->size())),
          path, "cannot put PixelData");
  }
}

void apply_edits(const CtSliceSpec& spec, DcmItem& ds, const std::filesystem::path& path) {
  for (const TagValue& edit : spec.extra) {
    put_string(ds, DcmTagKey(edit.tag.group, edit.tag.element), edit.value, path);
  }
  for (const Tag& tag : spec.omit) {
    // Absent already is fine: omitting is idempotent.
    ds.findAndDeleteElement(DcmTagKey(tag.group, tag.element), /*allOccurrences=*/OFTrue);
  }
}

// DCMTK's JPEG-LS encoder pads an odd-length code stream to even length with a byte it never
// initialises, so the same pixels gave different files. Every byte after the last EOI marker
// (FF D9) of a fragment is padding: set it to zero, the padding PS3.5 A.4 allows. FF D9 cannot
// occur inside entropy-coded data (JPEG stuffs FF 00, JPEG-LS stuffs a zero bit after FF), so
// the last one is the end of the image.
void zero_padding_after_eoi(DcmDataset& ds, E_TransferSyntax xfer,
                            const DcmRepresentationParameter* params,
                            const std::filesystem::path& path) {
  DcmElement* element = nullptr;
  check(ds.findAndGetElement(DCM_PixelData, element), path, "no PixelData after encoding");
  DcmPixelSequence* fragments = nullptr;
  check(static_cast<DcmPixelData*>(element)->getEncapsulatedRepresentation(xfer, params, fragments),
        path, "no encapsulated PixelData after encoding");
  for (unsigned long n = 1; n < fragments->card(); ++n) {  // item 0 is the offset table
    DcmPixelItem* item = nullptr;
    Uint8* bytes = nullptr;
    if (fragments->getItem(item, n).bad() || item->getUint8Array(bytes).bad() || !bytes) continue;
    const Uint32 length = item->getLength();
    for (Uint32 end = length; end >= 2; --end) {
      if (bytes[end - 2] == 0xFF && bytes[end - 1] == 0xD9) {
        std::fill(bytes + end, bytes + length, Uint8{0});
        break;
      }
    }
  }
}

void compress(const CtSliceSpec& spec, DcmDataset& ds, const std::filesystem::path& path) {
  register_encoders();
  const E_TransferSyntax xfer = to_dcmtk(spec.transfer_syntax);
  // Lossless parameters for each codec: JPEG process 14 with predictor 1 and no point
  // transform (the common "JPEG lossless SV1"), JPEG-LS with zero deviation.
  DJ_RPLossless jpeg_params(1, 0);
  DJLSRepresentationParameter jpeg_ls_params(0, OFTrue);
  DcmRLERepresentationParameter rle_params;
  const DcmRepresentationParameter* params = nullptr;
  switch (spec.transfer_syntax) {
    case TransferSyntax::jpeg_lossless:
      params = &jpeg_params;
      break;
    case TransferSyntax::jpeg_ls_lossless:
      params = &jpeg_ls_params;
      break;
    case TransferSyntax::rle_lossless:
      params = &rle_params;
      break;
    default:
      return;
  }
  check(ds.chooseRepresentation(xfer, params), path,
        std::string("cannot encode pixels as ") + to_uid(spec.transfer_syntax));
  if (!ds.canWriteXfer(xfer)) {
    fail(path, std::string("DCMTK cannot encode these pixels as ") + to_uid(spec.transfer_syntax));
  }
  if (spec.transfer_syntax != TransferSyntax::rle_lossless) {
    zero_padding_after_eoi(ds, xfer, params, path);
  }
}

// Appends one explicit-VR little-endian element, the only encoding a file meta header has.
void append_meta_element(std::string& out, std::uint16_t element, const char* vr,
                         std::string value) {
  const auto put16 = [&out](std::uint32_t v) {
    out += static_cast<char>(v & 0xFFu);
    out += static_cast<char>((v >> 8) & 0xFFu);
  };
  const bool is_ob = vr[0] == 'O' && vr[1] == 'B';
  if (value.size() % 2 != 0) value += (vr[0] == 'U' && vr[1] == 'I') || is_ob ? '\0' : ' ';
  put16(0x0002);
  put16(element);
  out.append(vr, 2);
  if (is_ob) {  // OB has two reserved bytes and a 32-bit length
    put16(0);
    put16(static_cast<std::uint32_t>(value.size()) & 0xFFFFu);
    put16(static_cast<std::uint32_t>(value.size()) >> 16);
  } else {
    put16(static_cast<std::uint32_t>(value.size()));
  }
  out += value;
}

// The file meta header (group 0002) for `spec`, assembled here rather than by DCMTK, whose own
// names its version (OFFIS_DCMTK_367) and would change the bytes of every file with an upgrade.
// SOP class and instance come from the spec fields, not from `extra` or `omit`.
std::string encode_meta_header(const CtSliceSpec& spec) {
  std::string body;
  append_meta_element(body, 0x0001, "OB", std::string("\0\1", 2));
  append_meta_element(body, 0x0002, "UI", spec.sop_class_uid);
  append_meta_element(body, 0x0003, "UI", spec.sop_instance_uid);
  append_meta_element(body, 0x0010, "UI", to_uid(spec.transfer_syntax));
  append_meta_element(body, 0x0012, "UI", std::string(kImplementationClassUid));
  append_meta_element(body, 0x0013, "SH", std::string(kImplementationVersionName));
  std::string length(4, '\0');
  for (std::size_t n = 0; n < 4; ++n) {
    length[n] = static_cast<char>((body.size() >> (8 * n)) & 0xFFu);
  }
  std::string header;
  append_meta_element(header, 0x0000, "UL", length);
  return header + body;
}

std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot reopen the written data set");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) fail(path, "cannot write the file");
}

}  // namespace

const char* to_uid(TransferSyntax syntax) {
  switch (syntax) {
    case TransferSyntax::implicit_little:
      return "1.2.840.10008.1.2";
    case TransferSyntax::explicit_little:
      return "1.2.840.10008.1.2.1";
    case TransferSyntax::explicit_big:
      return "1.2.840.10008.1.2.2";
    case TransferSyntax::deflated_little:
      return "1.2.840.10008.1.2.1.99";
    case TransferSyntax::jpeg_lossless:
      return "1.2.840.10008.1.2.4.70";
    case TransferSyntax::jpeg_ls_lossless:
      return "1.2.840.10008.1.2.4.80";
    case TransferSyntax::rle_lossless:
      return "1.2.840.10008.1.2.5";
  }
  return "";
}

void write_ct_slice(const CtSliceSpec& spec, const std::filesystem::path& path) {
  DcmDataset ds;
  put_attributes(spec, ds, path);
  put_pixels(spec, ds, path);
  apply_edits(spec, ds, path);
  if (is_encapsulated(spec.transfer_syntax)) compress(spec, ds, path);

  // DCMTK encodes the data set (byte order, VRs, deflate, encapsulation); the container around
  // it is ours, so that every layout in Container comes out the same way.
  check(ds.saveFile(path.c_str(), to_dcmtk(spec.transfer_syntax), EET_ExplicitLength, EGL_recalcGL,
                    EPD_noChange),
        path, "cannot write the data set");
  if (spec.container == Container::dataset_only && !spec.truncate_to_bytes) return;

  std::string bytes;
  if (spec.container == Container::part10) bytes = std::string(128, '\0') + "DICM";
  if (spec.container != Container::dataset_only) bytes += encode_meta_header(spec);
  bytes += read_bytes(path);
  if (spec.truncate_to_bytes && *spec.truncate_to_bytes < bytes.size()) {
    bytes.resize(static_cast<std::size_t>(*spec.truncate_to_bytes));
  }
  write_bytes(path, bytes);
}

std::vector<CtSliceSpec> make_axial_series(const SeriesLayout& layout) {
  const auto& o = layout.orientation;
  const Vec3 row{o[0], o[1], o[2]};
  const Vec3 column{o[3], o[4], o[5]};
  const Vec3 normal{row[1] * column[2] - row[2] * column[1],
                    row[2] * column[0] - row[0] * column[2],
                    row[0] * column[1] - row[1] * column[0]};
  const Vec3 step = layout.slice_step.value_or(Vec3{normal[0] * layout.slice_spacing,
                                                    normal[1] * layout.slice_spacing,
                                                    normal[2] * layout.slice_spacing});
  const std::string& seed = layout.uid_seed;
  const std::string study_uid = make_uid(seed + "/study");
  const std::string series_uid = make_uid(seed + "/series");
  const std::string frame_uid = make_uid(seed + "/frame-of-reference");
  const std::string thickness = format_ds(layout.slice_thickness.value_or(layout.slice_spacing));
  const std::string spacing = format_ds(layout.slice_spacing);
  const std::string intercept = format_ds(layout.rescale_intercept);
  const std::string slope = format_ds(layout.rescale_slope);
  const std::string orientation = format_ds(std::span<const double>(o));
  const std::string pixel_spacing = format_ds(std::span<const double>(layout.pixel_spacing));

  std::vector<CtSliceSpec> specs;
  specs.reserve(static_cast<std::size_t>(std::max(layout.slices, 0)));
  for (int k = 0; k < layout.slices; ++k) {
    CtSliceSpec spec;
    spec.sop_instance_uid = make_uid(seed + "/instance/" + std::to_string(k));
    spec.study_instance_uid = study_uid;
    spec.series_instance_uid = series_uid;
    spec.frame_of_reference_uid = frame_uid;
    spec.series_description = layout.series_description;
    spec.series_number = std::to_string(layout.series_number);
    spec.instance_number = std::to_string(k + 1);

    const Vec3 position{layout.origin[0] + k * step[0], layout.origin[1] + k * step[1],
                        layout.origin[2] + k * step[2]};
    spec.image_position_patient = format_ds(std::span<const double>(position));
    spec.image_orientation_patient = orientation;
    spec.pixel_spacing = pixel_spacing;
    spec.slice_thickness = thickness;
    spec.spacing_between_slices = spacing;
    spec.slice_location =
        format_ds(position[0] * normal[0] + position[1] * normal[1] + position[2] * normal[2]);

    spec.rows = layout.rows;
    spec.columns = layout.columns;
    spec.bits_allocated = layout.bits_allocated;
    spec.bits_stored = layout.bits_stored;
    spec.high_bit = layout.high_bit;
    spec.pixel_representation = layout.pixel_representation;
    spec.rescale_intercept = intercept;
    spec.rescale_slope = slope;
    spec.transfer_syntax = layout.transfer_syntax;

    spec.pixels.assign(std::size_t{layout.rows} * layout.columns, 0);
    if (layout.stored_value || layout.hu) {
      std::size_t n = 0;
      for (int j = 0; j < layout.rows; ++j) {
        for (int i = 0; i < layout.columns; ++i) {
          const std::int32_t stored =
              layout.stored_value ? layout.stored_value(i, j, k)
                                  : stored_from_hu(layout.hu(i, j, k), layout.rescale_intercept,
                                                   layout.rescale_slope, layout.bits_stored,
                                                   layout.pixel_representation);
          spec.pixels[n++] = to_pixel_word(stored);
        }
      }
    }
    specs.push_back(std::move(spec));
  }
  return specs;
}

std::vector<std::filesystem::path> write_series(const std::vector<CtSliceSpec>& specs,
                                                const std::filesystem::path& directory,
                                                const FileNamer& name) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) fail(directory, "cannot create the directory: " + error.message());
  std::vector<std::filesystem::path> paths;
  paths.reserve(specs.size());
  for (std::size_t index = 0; index < specs.size(); ++index) {
    std::string file_name;
    if (name) {
      file_name = name(index, specs[index]);
    } else {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "slice_%04zu.dcm", index);
      file_name = buffer;
    }
    paths.push_back(directory / file_name);
    write_ct_slice(specs[index], paths.back());
  }
  return paths;
}

std::int32_t stored_from_hu(double hu, double rescale_intercept, double rescale_slope,
                            std::uint16_t bits_stored, std::uint16_t pixel_representation) {
  const int bits = std::clamp<int>(bits_stored, 1, 31);
  const std::int64_t range = std::int64_t{1} << bits;
  const std::int64_t low = pixel_representation == 0 ? 0 : -range / 2;
  const std::int64_t high = pixel_representation == 0 ? range - 1 : range / 2 - 1;
  const double raw = (hu - rescale_intercept) / rescale_slope;
  if (std::isnan(raw)) return 0;
  if (raw <= static_cast<double>(low)) return static_cast<std::int32_t>(low);
  if (raw >= static_cast<double>(high)) return static_cast<std::int32_t>(high);
  return static_cast<std::int32_t>(std::lround(raw));
}

std::uint64_t fnv1a64(std::string_view bytes) {
  std::uint64_t hash = 0xcbf29ce484222325ull;
  for (const char c : bytes) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 0x100000001b3ull;
  }
  return hash;
}

std::string make_uid(std::string_view key) {
  // Root (28 characters) + at most 20 digits: well inside the 64-character limit, and a
  // decimal rendering of an integer never has the leading zero UIDs forbid.
  return std::string(kUidRoot) + std::to_string(fnv1a64(key));
}

std::string format_ds(double value) {
  if (value == 0.0) return "0";  // also turns −0 into 0
  char buffer[64];
  auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  std::string text(buffer, result.ptr);
  // DS holds 16 characters; drop significant digits until it fits.
  for (int precision = 16; text.size() > 16 && precision > 0; --precision) {
    result =
        std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::general, precision);
    text.assign(buffer, result.ptr);
  }
  return text;
}

std::string format_ds(std::span<const double> values) {
  std::string text;
  for (std::size_t n = 0; n < values.size(); ++n) {
    if (n > 0) text += '\\';
    text += format_ds(values[n]);
  }
  return text;
}

}  // namespace typemerge::ct_writer
