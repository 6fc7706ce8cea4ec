#include "seg/seg_reader.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmfg/fginterface.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmfg/fgseg.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <new>

#include "dicom/header_reader.h"
#include "dicom/nesting_prescan.h"
#include "dicom/pixel_reader.h"
#include "seg/cielab.h"
#include "seg/frame_grid.h"

namespace typemerge::seg {
namespace {

// Label Map Segmentation Storage (DICOM 2024): one label per pixel instead of one frame per
// segment; DCMTK 3.6.7 predates it.
constexpr const char* kLabelMapSegmentationStorage = "1.2.840.10008.5.1.4.1.1.66.7";
// Values longer than this stay in the file until first accessed (the pixel data).
constexpr Uint32 kLazyValueBytes = 4096;
constexpr std::uint32_t kMaxFrames = 1u << 20;
constexpr double kUnitTolerance = 1e-3;  // orientation cosines: unit length, orthogonal

using Vec3 = core::Vec3;

[[noreturn]] void fail(const std::string& reason) { throw SegError{"DICOM SEG: " + reason}; }

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 scaled(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }

void register_decoders_once() {
  static std::once_flag once;
  std::call_once(once, [] {
    dicom::silence_dcmtk_log();
    DcmRLEDecoderRegistration::registerCodecs();
  });
}

// DcmSegmentation reads its segments and functional groups without its frames only through
// protected members; this opens them.
class SegDocument : public DcmSegmentation {
 public:
  OFCondition read_without_pixels(DcmItem& dataset) { return readWithoutPixelData(dataset); }
};

bool is_jpeg2000(E_TransferSyntax xfer) {
  return xfer == EXS_JPEG2000LosslessOnly || xfer == EXS_JPEG2000 ||
         xfer == EXS_JPEG2000MulticomponentLosslessOnly || xfer == EXS_JPEG2000Multicomponent;
}

std::string text_of(DcmItem& item, const DcmTagKey& tag) {
  OFString value;
  if (item.findAndGetOFString(tag, value).bad()) return {};
  std::string text = value.c_str();
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  return text;
}

// An opened SEG: the file (pixel data still on disk) and what its header says.
struct OpenedSeg {
  DcmFileFormat format;
  SegHeader header;
  std::uint16_t rows = 0, columns = 0;
};

void load_dataset(const std::filesystem::path& file, DcmFileFormat& format) {
  register_decoders_once();
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error)) fail("not a readable file");
  // DCMTK parses sequences recursively; a crafted nesting would overflow the stack.
  const dicom::NestingReport nesting = dicom::prescan_nesting(file);
  if (!nesting.error.empty()) fail(nesting.error);
  const std::uint64_t file_bytes = std::filesystem::file_size(file, error);
  if (nesting.pixel_data_offset && nesting.pixel_data_length != 0xFFFFFFFFu &&
      *nesting.pixel_data_offset + std::uint64_t{nesting.pixel_data_length} > file_bytes) {
    fail("truncated file: its pixel data ends past the end of the file");
  }
  const OFCondition loaded = format.loadFile(OFFilename(file.c_str()), EXS_Unknown, EGL_noChange,
                                             kLazyValueBytes, ERM_autoDetect);
  if (loaded.bad()) fail(std::string("cannot read the file: ") + loaded.text());
}

void check_sop_class(DcmDataset& dataset) {
  const std::string sop_class = text_of(dataset, DCM_SOPClassUID);
  if (sop_class == kLabelMapSegmentationStorage) {
    fail("Label Map Segmentation Storage is not supported (DCMTK 3.6.7, which reads SEG here, "
         "predates it; convert it to a binary SEG or a label map NRRD/NIfTI)");
  }
  if (sop_class != UID_SegmentationStorage) {
    // Only a standard SOP class's name: a file's own text never reaches a message.
    const char* name = dcmFindNameOfUID(sop_class.c_str(), nullptr);
    fail(std::string("not a Segmentation Storage object (SOP class ") +
         (sop_class.empty() ? "missing" : (name != nullptr ? name : "unknown")) + ")");
  }
}

std::uint16_t uint16_of(DcmItem& item, const DcmTagKey& tag, const char* name) {
  Uint16 value = 0;
  if (item.findAndGetUint16(tag, value).bad()) fail(std::string("no ") + name);
  return value;
}

void read_image_attributes(DcmDataset& dataset, OpenedSeg& seg) {
  SegHeader& header = seg.header;
  const std::string type = text_of(dataset, DCM_SegmentationType);
  if (type == "LABELMAP") {
    fail("Segmentation Type LABELMAP is not supported (DCMTK 3.6.7 reads BINARY and "
         "FRACTIONAL only)");
  }
  if (type == "BINARY") {
    header.kind = SegKind::binary;
  } else if (type == "FRACTIONAL") {
    header.kind = SegKind::fractional;
  } else {
    fail("Segmentation Type missing or not BINARY or FRACTIONAL");
  }
  seg.rows = uint16_of(dataset, DCM_Rows, "Rows");
  seg.columns = uint16_of(dataset, DCM_Columns, "Columns");
  if (seg.rows == 0 || seg.columns == 0) fail("empty frames (Rows or Columns 0)");
  const std::uint16_t bits = uint16_of(dataset, DCM_BitsAllocated, "Bits Allocated");
  const std::uint16_t samples = uint16_of(dataset, DCM_SamplesPerPixel, "Samples per Pixel");
  if (samples != 1) fail("Samples per Pixel " + std::to_string(samples) + " (1 expected)");
  if (header.kind == SegKind::binary && bits != 1) {
    fail("a binary SEG with Bits Allocated " + std::to_string(bits) + " (1 expected)");
  }
  if (header.kind == SegKind::fractional) {
    if (bits != 8) {
      fail("a fractional SEG with Bits Allocated " + std::to_string(bits) + " (8 expected)");
    }
    header.max_fractional_value =
        uint16_of(dataset, DCM_MaximumFractionalValue, "Maximum Fractional Value");
    if (header.max_fractional_value == 0 || header.max_fractional_value > 255) {
      fail("Maximum Fractional Value " + std::to_string(header.max_fractional_value) +
           " outside 1..255");
    }
  }
  const E_TransferSyntax xfer = dataset.getOriginalXfer();
  if (is_jpeg2000(xfer)) {
    fail(std::string("frames compressed with ") + DcmXfer(xfer).getXferName() +
         ", which DCMTK 3.6.7 does not decode");
  }
  if (DcmXfer(xfer).isEncapsulated() && xfer != EXS_RLELossless) {
    fail(std::string("frames compressed with ") + DcmXfer(xfer).getXferName() +
         ", which the SEG reader does not decode (native, deflated and RLE are read)");
  }
}

// Segment numbers from the Segment Sequence itself, in file order.
std::vector<std::uint16_t> segment_numbers(DcmDataset& dataset) {
  std::vector<std::uint16_t> numbers;
  DcmSequenceOfItems* sequence = nullptr;
  if (dataset.findAndGetSequence(DCM_SegmentSequence, sequence).bad() || sequence == nullptr) {
    fail("no Segment Sequence");
  }
  for (unsigned long i = 0; i < sequence->card(); ++i) {
    DcmItem* item = sequence->getItem(i);
    Uint16 number = 0;
    if (item == nullptr || item->findAndGetUint16(DCM_SegmentNumber, number).bad() || number == 0) {
      fail("segment " + std::to_string(i + 1) + " has no valid Segment Number");
    }
    if (std::find(numbers.begin(), numbers.end(), number) != numbers.end()) {
      fail("Segment Number " + std::to_string(number) + " appears twice");
    }
    numbers.push_back(number);
  }
  if (numbers.empty()) fail("no segments");
  return numbers;
}

void read_segments(DcmDataset& dataset, SegDocument& document, SegHeader& header) {
  const std::vector<std::uint16_t> numbers = segment_numbers(dataset);
  if (document.getNumberOfSegments() != numbers.size()) fail("unreadable Segment Sequence");
  for (std::size_t i = 0; i < numbers.size(); ++i) {
    DcmSegment* segment = document.getSegment(i + 1);
    if (segment == nullptr) fail("unreadable segment " + std::to_string(i + 1));
    SegSegmentInfo info;
    info.number = numbers[i];
    OFString label;
    if (segment->getSegmentLabel(label).good()) info.name = label.c_str();
    while (!info.name.empty() && info.name.back() == ' ') info.name.pop_back();
    Uint16 l = 0, a = 0, b = 0;
    if (segment->getRecommendedDisplayCIELabValue(l, a, b).good()) {
      info.srgb = srgb_from_dicom_cielab(l, a, b);
    }
    header.segments.push_back(std::move(info));
  }
}

struct FrameGeometry {
  Vec3 row{}, column{};                // direction cosines
  double row_spacing = 0, column_spacing = 0;  // mm between rows, between columns
  std::optional<double> spacing_between_slices;
  std::optional<double> slice_thickness;
};

FrameGeometry frame_geometry(FGInterface& groups, Uint32 frame) {
  FrameGeometry geometry;
  auto* orientation =
      dynamic_cast<FGPlaneOrientationPatient*>(groups.get(frame, DcmFGTypes::EFG_PLANEORIENTPATIENT));
  if (orientation == nullptr ||
      orientation->getImageOrientationPatient(geometry.row[0], geometry.row[1], geometry.row[2],
                                              geometry.column[0], geometry.column[1],
                                              geometry.column[2])
          .bad()) {
    fail("frame " + std::to_string(frame + 1) + " has no Plane Orientation (Patient)");
  }
  auto* measures =
      dynamic_cast<FGPixelMeasures*>(groups.get(frame, DcmFGTypes::EFG_PIXELMEASURES));
  if (measures == nullptr || measures->getPixelSpacing(geometry.row_spacing, 0).bad() ||
      measures->getPixelSpacing(geometry.column_spacing, 1).bad()) {
    fail("frame " + std::to_string(frame + 1) + " has no Pixel Spacing");
  }
  Float64 value = 0;
  if (measures->getSpacingBetweenSlices(value).good()) geometry.spacing_between_slices = value;
  if (measures->getSliceThickness(value).good()) geometry.slice_thickness = value;
  for (double v : {geometry.row[0], geometry.row[1], geometry.row[2], geometry.column[0],
                   geometry.column[1], geometry.column[2], geometry.row_spacing,
                   geometry.column_spacing}) {
    if (!std::isfinite(v)) fail("non-finite orientation or pixel spacing");
  }
  if (!(geometry.row_spacing > 0) || !(geometry.column_spacing > 0)) {
    fail("Pixel Spacing not positive");
  }
  if (std::abs(dot(geometry.row, geometry.row) - 1) > kUnitTolerance * 2 ||
      std::abs(dot(geometry.column, geometry.column) - 1) > kUnitTolerance * 2 ||
      std::abs(dot(geometry.row, geometry.column)) > kUnitTolerance) {
    fail("Image Orientation (Patient) is not two orthogonal unit vectors");
  }
  return geometry;
}

bool same_geometry(const FrameGeometry& a, const FrameGeometry& b) {
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(a.row[axis] - b.row[axis]) > kUnitTolerance ||
        std::abs(a.column[axis] - b.column[axis]) > kUnitTolerance) {
      return false;
    }
  }
  return std::abs(a.row_spacing - b.row_spacing) <= kUnitTolerance * a.row_spacing &&
         std::abs(a.column_spacing - b.column_spacing) <= kUnitTolerance * a.column_spacing;
}

void read_frames_geometry(DcmDataset& dataset, SegDocument& document, OpenedSeg& seg) {
  SegHeader& header = seg.header;
  Sint32 declared_frames = 0;
  if (dataset.findAndGetSint32(DCM_NumberOfFrames, declared_frames).bad() ||
      declared_frames <= 0) {
    fail("no Number of Frames");
  }
  if (static_cast<std::uint32_t>(declared_frames) > kMaxFrames) {
    fail(std::to_string(declared_frames) + " frames (at most " + std::to_string(kMaxFrames) +
         " are read)");
  }
  FGInterface& groups = document.getFunctionalGroups();
  if (groups.getNumberOfFrames() != static_cast<std::size_t>(declared_frames)) {
    fail("Number of Frames " + std::to_string(declared_frames) + " but " +
         std::to_string(groups.getNumberOfFrames()) + " per-frame functional groups");
  }
  const auto frames = static_cast<Uint32>(declared_frames);

  const FrameGeometry first = frame_geometry(groups, 0);
  const Vec3 normal = cross(first.row, first.column);
  std::vector<Vec3> positions(frames);
  std::vector<double> distances(frames);
  header.frame_segment.resize(frames);
  for (Uint32 f = 0; f < frames; ++f) {
    if (f > 0 && !same_geometry(first, frame_geometry(groups, f))) {
      fail("frame " + std::to_string(f + 1) +
           " differs from the first in orientation or pixel spacing");
    }
    auto* position =
        dynamic_cast<FGPlanePosPatient*>(groups.get(f, DcmFGTypes::EFG_PLANEPOSPATIENT));
    Vec3& p = positions[f];
    if (position == nullptr || position->getImagePositionPatient(p[0], p[1], p[2]).bad() ||
        !std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      fail("frame " + std::to_string(f + 1) + " has no valid Plane Position (Patient)");
    }
    distances[f] = dot(p, normal);
    auto* identification =
        dynamic_cast<FGSegmentation*>(groups.get(f, DcmFGTypes::EFG_SEGMENTATION));
    Uint16 number = 0;
    if (identification == nullptr || identification->getReferencedSegmentNumber(number).bad()) {
      fail("frame " + std::to_string(f + 1) + " names no segment");
    }
    const bool known = std::any_of(header.segments.begin(), header.segments.end(),
                                   [&](const SegSegmentInfo& s) { return s.number == number; });
    if (!known) {
      fail("frame " + std::to_string(f + 1) + " refers to segment " + std::to_string(number) +
           ", which is not in the Segment Sequence");
    }
    header.frame_segment[f] = number;
  }

  // Every frame must lie on the line through the first along the normal (no shear).
  const double in_plane_tolerance = 0.1 * std::min(first.row_spacing, first.column_spacing);
  for (Uint32 f = 1; f < frames; ++f) {
    const Vec3 offset = {positions[f][0] - positions[0][0], positions[f][1] - positions[0][1],
                         positions[f][2] - positions[0][2]};
    const double along = dot(offset, normal);
    const Vec3 in_plane = {offset[0] - along * normal[0], offset[1] - along * normal[1],
                           offset[2] - along * normal[2]};
    if (std::sqrt(dot(in_plane, in_plane)) > in_plane_tolerance) {
      fail("frame " + std::to_string(f + 1) +
           " is not stacked along the slice normal with the first (a sheared or mixed grid)");
    }
  }

  const double single_step =
      first.spacing_between_slices && *first.spacing_between_slices > 0 &&
              std::isfinite(*first.spacing_between_slices)
          ? *first.spacing_between_slices
          : (first.slice_thickness && *first.slice_thickness > 0 &&
                     std::isfinite(*first.slice_thickness)
                 ? *first.slice_thickness
                 : 1.0);
  const FramePlacement placement =
      place_frames(distances, first.spacing_between_slices, single_step, kMaxSlices);
  if (!placement.ok()) fail(placement.error);
  header.frame_slice = placement.slice_of_frame;
  header.size = {seg.columns, seg.rows, placement.slices};

  // Slice 0 is at the lowest distance; its in-plane place is the first frame's.
  const double shift = placement.first_mm - distances[0];
  core::IndexToPatient& geometry = header.geometry;
  geometry.origin = {positions[0][0] + shift * normal[0], positions[0][1] + shift * normal[1],
                     positions[0][2] + shift * normal[2]};
  geometry.axes = {scaled(first.row, first.column_spacing),
                   scaled(first.column, first.row_spacing), scaled(normal, placement.step_mm)};
}

void open_seg(const std::filesystem::path& file, OpenedSeg& seg) {
  load_dataset(file, seg.format);
  DcmDataset& dataset = *seg.format.getDataset();
  check_sop_class(dataset);
  read_image_attributes(dataset, seg);
  SegDocument document;
  // Its result only reports problems with modules the reader does not use (equipment,
  // series); what is used is checked below.
  (void)document.read_without_pixels(dataset);
  read_segments(dataset, document, seg.header);
  read_frames_geometry(dataset, document, seg);
}

// The pixel data as bytes, checked to hold every frame.
const Uint8* pixel_bytes(DcmDataset& dataset, const OpenedSeg& seg, std::uint64_t needed) {
  if (dataset.getOriginalXfer() == EXS_RLELossless) {
    if (dataset.chooseRepresentation(EXS_LittleEndianExplicit, nullptr).bad() ||
        !dataset.canWriteXfer(EXS_LittleEndianExplicit)) {
      fail("cannot decode its RLE-compressed frames");
    }
  }
  DcmElement* element = nullptr;
  if (dataset.findAndGetElement(DCM_PixelData, element).bad() || element == nullptr) {
    fail("no Pixel Data");
  }
  if (element->getLength() < needed) {
    fail("Pixel Data of " + std::to_string(element->getLength()) + " bytes, " +
         std::to_string(needed) + " needed for " + std::to_string(seg.header.frame_slice.size()) +
         " frames of " + std::to_string(seg.columns) + " x " + std::to_string(seg.rows));
  }
  Uint8* bytes = nullptr;
  if (element->getUint8Array(bytes).good() && bytes != nullptr) return bytes;
  // Pixel Data read as OW (implicit VR): DCMTK holds the words in host order; on a
  // little-endian host their bytes are the stream's.
  static_assert(std::endian::native == std::endian::little);
  Uint16* words = nullptr;
  if (element->getUint16Array(words).good() && words != nullptr) {
    return reinterpret_cast<const Uint8*>(words);
  }
  fail("unreadable Pixel Data");
}

// Calls visit(i, j) for every pixel of frame f inside its segment.
template <typename Visit>
void for_each_inside(const Uint8* pixels, const SegHeader& header, std::size_t frame,
                     Visit&& visit) {
  const auto nx = static_cast<std::uint64_t>(header.size.nx);
  const auto ny = static_cast<std::uint64_t>(header.size.ny);
  const std::uint64_t begin = frame * nx * ny;
  if (header.kind == SegKind::binary) {
    for (std::uint64_t p = 0; p < nx * ny; ++p) {
      const std::uint64_t bit = begin + p;
      // A zero byte holds 8 outside pixels (most of a sparse segmentation).
      if ((bit & 7) == 0 && p + 8 <= nx * ny && pixels[bit >> 3] == 0) {
        p += 7;
        continue;
      }
      if ((pixels[bit >> 3] >> (bit & 7)) & 1u) {
        visit(static_cast<std::int64_t>(p % nx), static_cast<std::int64_t>(p / nx));
      }
    }
    return;
  }
  const unsigned max_value = header.max_fractional_value;
  for (std::uint64_t p = 0; p < nx * ny; ++p) {
    if (2u * pixels[begin + p] >= max_value) {
      visit(static_cast<std::int64_t>(p % nx), static_cast<std::int64_t>(p / nx));
    }
  }
}

}  // namespace

bool is_seg_file(const std::filesystem::path& file) {
  try {
    register_decoders_once();
    std::error_code error;
    if (!std::filesystem::is_regular_file(file, error)) return false;
    if (!dicom::prescan_nesting(file).error.empty()) return false;
    DcmFileFormat format;
    if (format.loadFileUntilTag(OFFilename(file.c_str()), EXS_Unknown, EGL_noChange,
                                kLazyValueBytes, ERM_autoDetect, DCM_SOPInstanceUID)
            .bad()) {
      return false;
    }
    const std::string sop_class = text_of(*format.getDataset(), DCM_SOPClassUID);
    return sop_class == UID_SegmentationStorage || sop_class == kLabelMapSegmentationStorage;
  } catch (const std::exception&) {
    return false;
  }
}

SegHeader read_seg_header(const std::filesystem::path& file) {
  try {
    OpenedSeg seg;
    open_seg(file, seg);
    return std::move(seg.header);
  } catch (const std::bad_alloc&) {
    fail("out of memory while reading the header");
  }
}

SegVolume read_seg(const std::filesystem::path& file, const SegReadOptions& options) {
  try {
    OpenedSeg seg;
    open_seg(file, seg);
    const SegHeader& header = seg.header;
    const std::uint64_t frame_pixels =
        static_cast<std::uint64_t>(seg.rows) * static_cast<std::uint64_t>(seg.columns);
    const std::uint64_t frames = header.frame_slice.size();
    const std::uint64_t needed = header.kind == SegKind::binary
                                     ? (frames * frame_pixels + 7) / 8
                                     : frames * frame_pixels;
    const Uint8* pixels = pixel_bytes(*seg.format.getDataset(), seg, needed);

    std::map<std::uint16_t, std::vector<std::size_t>> frames_of;
    for (std::size_t f = 0; f < frames; ++f) frames_of[header.frame_segment[f]].push_back(f);

    SegVolume result;
    result.warnings = header.warnings;
    std::vector<core::Volume>& layers = result.labels.layers;
    for (const SegSegmentInfo& info : header.segments) {
      const std::vector<std::size_t>& own = frames_of[info.number];
      // The first layer where none of its voxels is taken.
      std::size_t layer = 0;
      for (; layer < layers.size(); ++layer) {
        bool overlaps = false;
        for (std::size_t f : own) {
          const std::int64_t k = header.frame_slice[f];
          const core::Volume& volume = layers[layer];
          for_each_inside(pixels, header, f, [&](std::int64_t i, std::int64_t j) {
            overlaps = overlaps || volume.at(i, j, k) != 0.0f;
          });
          if (overlaps) break;
        }
        if (!overlaps) break;
      }
      if (layer == layers.size()) {
        if ((layers.size() + 1) * header.layer_bytes() > options.max_volume_bytes) {
          fail("its overlapping segments need " + std::to_string(layers.size() + 1) +
               " layers of " + std::to_string(header.layer_bytes() >> 20) +
               " MiB, more than the memory limit");
        }
        layers.emplace_back(header.size, header.geometry);
      }
      core::Volume& volume = layers[layer];
      const auto label = static_cast<float>(info.number);
      for (std::size_t f : own) {
        const std::int64_t k = header.frame_slice[f];
        for_each_inside(pixels, header, f,
                        [&](std::int64_t i, std::int64_t j) { volume.at(i, j, k) = label; });
      }
      result.labels.segments.push_back({info.number, layer, info.name, info.srgb});
    }
    return result;
  } catch (const std::bad_alloc&) {
    fail("out of memory while reading the frames");
  }
}

}  // namespace typemerge::seg
