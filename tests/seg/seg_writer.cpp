#include "seg/seg_writer.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmfg/fgfracon.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>

#include <memory>
#include <sstream>
#include <stdexcept>

namespace typemerge::test {
namespace {

void check(const OFCondition& condition, const std::string& what) {
  if (condition.bad()) throw std::runtime_error("writing a SEG: " + what + ": " + condition.text());
}

OFString decimal(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str().c_str();
}

}  // namespace

std::vector<std::uint8_t> box_pixels(const SynthSeg& seg, int row0, int row1, int col0, int col1,
                                     std::uint8_t value) {
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(seg.rows) * seg.columns, 0);
  for (int r = row0; r <= row1; ++r) {
    for (int c = col0; c <= col1; ++c) pixels[static_cast<std::size_t>(r) * seg.columns + c] = value;
  }
  return pixels;
}

void write_seg(const SynthSeg& spec, const std::filesystem::path& file) {
  IODGeneralEquipmentModule::EquipmentInfo equipment("typemerge tests", "synthetic", "0", "0");
  ContentIdentificationMacro content("1", "SYNTH", "synthetic segmentation",
                                     spec.content_creator.c_str());
  DcmSegmentation* raw = nullptr;
  if (spec.fractional) {
    check(DcmSegmentation::createFractionalSegmentation(raw, spec.rows, spec.columns,
                                                        DcmSegTypes::SFT_PROBABILITY,
                                                        spec.max_fractional_value, equipment,
                                                        content),
          "create");
  } else {
    check(DcmSegmentation::createBinarySegmentation(raw, spec.rows, spec.columns, equipment,
                                                    content),
          "create");
  }
  std::unique_ptr<DcmSegmentation> seg(raw);
  seg->setCheckFGOnWrite(OFFalse);
  seg->setCheckDimensionsOnWrite(OFFalse);
  check(seg->getPatient().setPatientName(spec.patient_name.c_str()), "patient name");
  check(seg->getPatient().setPatientID(spec.patient_id.c_str()), "patient id");
  check(seg->getSeries().setSeriesNumber("1"), "series number");
  char uid[100];
  check(seg->getFrameOfReference().setFrameOfReferenceUID(
            dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT)),
        "frame of reference");

  FGPixelMeasures measures;
  check(measures.setPixelSpacing(decimal(spec.pixel_spacing[0]) + "\\" +
                                 decimal(spec.pixel_spacing[1])),
        "pixel spacing");
  check(measures.setSliceThickness(decimal(spec.slice_thickness)), "thickness");
  if (spec.spacing_between_slices) {
    check(measures.setSpacingBetweenSlices(decimal(*spec.spacing_between_slices)), "spacing");
  }
  FGPlaneOrientationPatient orientation;
  const auto& o = spec.orientation;
  check(orientation.setImageOrientationPatient(decimal(o[0]), decimal(o[1]), decimal(o[2]),
                                               decimal(o[3]), decimal(o[4]), decimal(o[5])),
        "orientation");
  check(seg->addForAllFrames(measures), "shared measures");
  check(seg->addForAllFrames(orientation), "shared orientation");

  for (const SynthSegment& s : spec.segments) {
    DcmSegment* segment = nullptr;
    CodeSequenceMacro category("85756007", "SCT", "Tissue");
    CodeSequenceMacro type("10200004", "SCT", "Liver");
    check(DcmSegment::create(segment, s.label.c_str(), category, type,
                             DcmSegTypes::SAT_AUTOMATIC, "synthetic"),
          "segment");
    if (s.cielab) {
      check(segment->setRecommendedDisplayCIELabValue((*s.cielab)[0], (*s.cielab)[1],
                                                      (*s.cielab)[2]),
            "colour");
    }
    Uint16 number = 0;
    check(seg->addSegment(segment, number), "add segment");
  }

  std::size_t frame_number = 1;
  for (const SynthFrame& frame : spec.frames) {
    FGPlanePosPatient position;
    check(position.setImagePositionPatient(decimal(frame.position[0]), decimal(frame.position[1]),
                                           decimal(frame.position[2])),
          "position");
    FGFrameContent frame_content;
    frame_content.setStackID("1");
    check(frame_content.setDimensionIndexValues(frame.segment, 0), "segment index");
    check(frame_content.setDimensionIndexValues(static_cast<Uint32>(frame_number++), 1),
          "position index");
    OFVector<FGBase*> groups;
    groups.push_back(&position);
    groups.push_back(&frame_content);
    // addFrame copies the pixels (and packs binary ones).
    std::vector<std::uint8_t> pixels = frame.pixels;
    check(seg->addFrame(pixels.data(), frame.segment, groups), "frame");
  }

  // One stack, frames indexed by their position in it.
  const OFString organization = dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
  IODMultiframeDimensionModule& dimensions = seg->getDimensions();
  check(dimensions.addDimensionIndex(DCM_ReferencedSegmentNumber, organization,
                                     DCM_SegmentIdentificationSequence, "segment"),
        "segment dimension");
  check(dimensions.addDimensionIndex(DCM_ImagePositionPatient, organization,
                                     DCM_PlanePositionSequence, "position"),
        "position dimension");
  auto* item = new IODMultiframeDimensionModule::DimensionOrganizationItem;
  check(item->setDimensionOrganizationUID(organization), "organization");
  dimensions.getDimensionOrganizationSequence().push_back(item);

  DcmFileFormat format;
  check(seg->writeDataset(*format.getDataset()), "dataset");
  check(format.saveFile(OFFilename(file.c_str()), EXS_LittleEndianExplicit), "save");
}

}  // namespace typemerge::test
