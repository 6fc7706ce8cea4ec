// Damaged and unsupported SEGs: each refused with a reason, none crashes.
#include <gtest/gtest.h>

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>

#include <fstream>
#include <functional>

#include "seg/seg_reader.h"
#include "seg/seg_writer.h"
#include "support/scratch_files.h"

namespace typemerge::seg {
namespace {

using test::SynthSeg;

SynthSeg small_seg() {
  SynthSeg spec;
  spec.segments = {{"Liver", std::nullopt}, {"Tumour", std::nullopt}};
  for (int k = 0; k < 3; ++k) {
    spec.frames.push_back({1, {0, 0, 2.0 * k}, test::box_pixels(spec, 0, 1, 0, 2)});
  }
  spec.frames.push_back({2, {0, 0, 2.0}, test::box_pixels(spec, 2, 3, 3, 5)});
  return spec;
}

class MalformedSeg : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::fresh_dir(std::string("seg_malformed_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    good_ = dir_ / "good.dcm";
    test::write_seg(small_seg(), good_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The good file changed by `edit`, saved in `xfer`.
  std::filesystem::path edited(const std::function<void(DcmDataset&)>& edit,
                               E_TransferSyntax xfer = EXS_LittleEndianExplicit) {
    DcmFileFormat format;
    EXPECT_TRUE(format.loadFile(good_.c_str()).good());
    edit(*format.getDataset());
    const auto file = dir_ / "edited.dcm";
    const OFCondition saved = format.saveFile(file.c_str(), xfer);
    EXPECT_TRUE(saved.good()) << saved.text();
    return file;
  }

  // Refused by both entry points with a message containing `expected`.
  static void expect_refused(const std::filesystem::path& file, const std::string& expected,
                             bool header_too = true) {
    try {
      read_seg(file);
      ADD_FAILURE() << "accepted; expected: " << expected;
    } catch (const SegError& error) {
      EXPECT_NE(std::string(error.what()).find(expected), std::string::npos) << error.what();
      EXPECT_EQ(std::string(error.what()).find(file.filename().string()), std::string::npos);
    }
    if (header_too) {
      EXPECT_THROW(read_seg_header(file), SegError);
    }
  }

  std::filesystem::path dir_, good_;
};

TEST_F(MalformedSeg, TheGoodFileReads) { EXPECT_NO_THROW(read_seg(good_)); }

TEST_F(MalformedSeg, NotDicomAndMissing) {
  const auto text = dir_ / "text.dcm";
  std::ofstream(text) << "this is not a DICOM file at all";
  expect_refused(text, "DICOM SEG");
  expect_refused(dir_ / "missing.dcm", "not a readable file");
}

TEST_F(MalformedSeg, TruncatedFiles) {
  const std::string bytes = test::read_file_bytes(good_);
  for (std::size_t keep : {std::size_t{0}, std::size_t{132}, bytes.size() / 3, bytes.size() / 2,
                           bytes.size() - 10}) {
    const auto cut = dir_ / ("cut" + std::to_string(keep) + ".dcm");
    std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(keep));
    EXPECT_THROW(read_seg(cut), SegError) << keep << " bytes";
  }
}

TEST_F(MalformedSeg, NotASegmentation) {
  expect_refused(edited([](DcmDataset& d) {
                   d.putAndInsertString(DCM_SOPClassUID, "1.2.840.10008.5.1.4.1.1.2");
                 }),
                 "not a Segmentation Storage object (SOP class CTImageStorage)");
  // A file's own text is never echoed.
  expect_refused(edited([](DcmDataset& d) {
                   d.putAndInsertString(DCM_SOPClassUID, "1.2.3.4.5.6.7");
                   d.putAndInsertString(DCM_SegmentationType, "DOE^JANE");
                 }),
                 "SOP class unknown");
  expect_refused(edited([](DcmDataset& d) {
                   d.putAndInsertString(DCM_SegmentationType, "DOE^JANE");
                 }),
                 "Segmentation Type missing or not BINARY or FRACTIONAL");
}

TEST_F(MalformedSeg, LabelMapSegIsRefusedByName) {
  expect_refused(edited([](DcmDataset& d) {
                   d.putAndInsertString(DCM_SOPClassUID, "1.2.840.10008.5.1.4.1.1.66.7");
                 }),
                 "Label Map");
  expect_refused(edited([](DcmDataset& d) {
                   d.putAndInsertString(DCM_SegmentationType, "LABELMAP");
                 }),
                 "LABELMAP");
}

TEST_F(MalformedSeg, Jpeg2000IsRefusedByName) {
  const auto file = edited(
      [](DcmDataset& d) {
        auto* sequence = new DcmPixelSequence(DCM_PixelSequenceTag);
        sequence->insert(new DcmPixelItem(DCM_PixelItemTag));  // basic offset table
        auto* fragment = new DcmPixelItem(DCM_PixelItemTag);
        const Uint8 junk[8] = {0xff, 0x4f, 0xff, 0x51, 0, 0, 0, 0};
        fragment->putUint8Array(junk, sizeof junk);
        sequence->insert(fragment);
        auto* pixels = new DcmPixelData(DCM_PixelData);
        pixels->putOriginalRepresentation(EXS_JPEG2000LosslessOnly, nullptr, sequence);
        d.insert(pixels, OFTrue);
      },
      EXS_JPEG2000LosslessOnly);
  expect_refused(file, "JPEG 2000");
}

TEST_F(MalformedSeg, PixelDataShorterThanItsFrames) {
  expect_refused(edited([](DcmDataset& d) {
                   const Uint8 bytes[2] = {0xff, 0xff};
                   d.putAndInsertUint8Array(DCM_PixelData, bytes, 2);
                 }),
                 "Pixel Data of", false);
}

TEST_F(MalformedSeg, NumberOfFramesDisagreesWithTheGroups) {
  expect_refused(edited([](DcmDataset& d) { d.putAndInsertString(DCM_NumberOfFrames, "7"); }),
                 "per-frame functional groups");
}

TEST_F(MalformedSeg, AFrameOfAnUnknownSegment) {
  expect_refused(edited([](DcmDataset& d) {
                   DcmItem* frame = nullptr;
                   ASSERT_TRUE(d.findAndGetSequenceItem(DCM_PerFrameFunctionalGroupsSequence,
                                                        frame, 1)
                                   .good());
                   DcmItem* identification = nullptr;
                   ASSERT_TRUE(frame->findAndGetSequenceItem(DCM_SegmentIdentificationSequence,
                                                             identification, 0)
                                   .good());
                   identification->putAndInsertUint16(DCM_ReferencedSegmentNumber, 9);
                 }),
                 "segment 9");
}

TEST_F(MalformedSeg, NoSegmentsOrNoGeometry) {
  expect_refused(edited([](DcmDataset& d) { delete d.remove(DCM_SegmentSequence); }),
                 "Segment Sequence");
  expect_refused(edited([](DcmDataset& d) { delete d.remove(DCM_SharedFunctionalGroupsSequence); }),
                 "functional groups");
  expect_refused(edited([](DcmDataset& d) { d.putAndInsertUint16(DCM_Rows, 0); }), "Rows");
  expect_refused(edited([](DcmDataset& d) { d.putAndInsertUint16(DCM_BitsAllocated, 8); }),
                 "Bits Allocated");
}

TEST_F(MalformedSeg, DeeplyNestedSequencesAreRefusedBeforeParsing) {
  DcmFileFormat format;
  ASSERT_TRUE(format.loadFile(good_.c_str()).good());
  DcmItem* item = format.getDataset();
  for (int depth = 0; depth < 100; ++depth) {
    DcmItem* inner = nullptr;
    ASSERT_TRUE(item->findOrCreateSequenceItem(DCM_ReferencedSeriesSequence, inner, 0).good());
    item = inner;
  }
  const auto file = dir_ / "nested.dcm";
  ASSERT_TRUE(format.saveFile(file.c_str(), EXS_LittleEndianExplicit).good());
  expect_refused(file, "nest");
}

}  // namespace
}  // namespace typemerge::seg
