// ct_writer: every file it writes is read back with DCMTK and checked attribute by attribute;
// broken values come back verbatim; each transfer syntax and container decodes to the same
// pixels; the same spec gives the same bytes.
#include "ct_writer/ct_writer.h"

#include <dcmtk/config/osconfig.h>  // must come before any other DCMTK header
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace typemerge::ct_writer {
namespace {

namespace fs = std::filesystem;

// Decoders are the reader's business, so the writer does not register them; the tests do.
const bool kDecodersRegistered = [] {
  DJDecoderRegistration::registerCodecs();
  DJLSDecoderRegistration::registerCodecs();
  DcmRLEDecoderRegistration::registerCodecs();
  return true;
}();

class CtWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string(info->test_suite_name()) + "_" + info->name();
    std::replace(name.begin(), name.end(), '/', '_');
    dir_ = fs::temp_directory_path() / ("typemerge_ct_writer_test_" + name);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);  // keep the evidence of a failure
  }
  fs::path dir_;
};

std::unique_ptr<DcmFileFormat> load(const fs::path& path) {
  auto file = std::make_unique<DcmFileFormat>();
  const OFCondition status =
      file->loadFile(path.c_str(), EXS_Unknown, EGL_noChange, DCM_MaxReadLength, ERM_autoDetect);
  if (status.bad()) {
    ADD_FAILURE() << "cannot load " << path << ": " << status.text();
    return nullptr;
  }
  return file;
}

std::string get_string(DcmItem& item, const DcmTagKey& key) {
  OFString value;
  if (item.findAndGetOFStringArray(key, value).bad()) return "<absent>";
  return value.c_str();
}

std::vector<std::uint16_t> get_pixels(DcmDataset& ds) {
  // Decompresses encapsulated pixel data in place; a no-op for native data.
  EXPECT_TRUE(ds.chooseRepresentation(EXS_LittleEndianExplicit, nullptr).good());
  const Uint16* words = nullptr;
  unsigned long count = 0;
  if (ds.findAndGetUint16Array(DCM_PixelData, words, &count).bad()) return {};
  return {words, words + count};
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A 12-bit ramp with a diagonal, different in every pixel of a 16×16 slice.
std::vector<std::uint16_t> test_pattern(int rows, int columns) {
  std::vector<std::uint16_t> pixels;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < columns; ++i) {
      pixels.push_back(static_cast<std::uint16_t>((i == j ? 3000 : 0) + 16 * j + i));
    }
  }
  return pixels;
}

TEST_F(CtWriterTest, WritesEveryAttributeOfTheSpec) {
  CtSliceSpec spec;
  spec.sop_instance_uid = make_uid("test/sop");
  spec.series_instance_uid = make_uid("test/series");
  spec.study_instance_uid = make_uid("test/study");
  spec.frame_of_reference_uid = make_uid("test/for");
  spec.patient_name = "CANARY^NAME";
  spec.patient_id = "CANARY-ID";
  spec.patient_birth_date = "19010203";
  spec.study_date = "20010203";
  spec.series_description = "canary description";
  spec.series_number = "7";
  spec.instance_number = "3";
  spec.image_position_patient = "-10.5\\20\\-30.25";
  spec.image_orientation_patient = "0\\1\\0\\0\\0\\-1";
  spec.pixel_spacing = "0.5\\0.75";
  spec.slice_thickness = "1.25";
  spec.rescale_intercept = "-1000";
  spec.rescale_slope = "2";
  spec.rows = 12;
  spec.columns = 10;
  spec.convolution_kernel = "B30f";
  spec.gantry_detector_tilt = "-12.5";
  spec.pixels = test_pattern(12, 10);

  const fs::path path = dir_ / "slice.dcm";
  write_ct_slice(spec, path);
  auto file = load(path);
  ASSERT_TRUE(file);
  DcmDataset& ds = *file->getDataset();
  EXPECT_EQ(get_string(ds, DCM_SOPClassUID), "1.2.840.10008.5.1.4.1.1.2");
  EXPECT_EQ(get_string(ds, DCM_SOPInstanceUID), spec.sop_instance_uid);
  EXPECT_EQ(get_string(ds, DCM_SeriesInstanceUID), spec.series_instance_uid);
  EXPECT_EQ(get_string(ds, DCM_StudyInstanceUID), spec.study_instance_uid);
  EXPECT_EQ(get_string(ds, DCM_FrameOfReferenceUID), spec.frame_of_reference_uid);
  EXPECT_EQ(get_string(ds, DCM_Modality), "CT");
  EXPECT_EQ(get_string(ds, DCM_ImageType), "ORIGINAL\\PRIMARY\\AXIAL");
  EXPECT_EQ(get_string(ds, DCM_PatientName), "CANARY^NAME");
  EXPECT_EQ(get_string(ds, DCM_PatientID), "CANARY-ID");
  EXPECT_EQ(get_string(ds, DCM_PatientBirthDate), "19010203");
  EXPECT_EQ(get_string(ds, DCM_StudyDate), "20010203");
  EXPECT_EQ(get_string(ds, DCM_SeriesDescription), "canary description");
  EXPECT_EQ(get_string(ds, DCM_SeriesNumber), "7");
  EXPECT_EQ(get_string(ds, DCM_InstanceNumber), "3");
  EXPECT_EQ(get_string(ds, DCM_ImagePositionPatient), "-10.5\\20\\-30.25");
  EXPECT_EQ(get_string(ds, DCM_ImageOrientationPatient), "0\\1\\0\\0\\0\\-1");
  EXPECT_EQ(get_string(ds, DCM_PixelSpacing), "0.5\\0.75");
  EXPECT_EQ(get_string(ds, DCM_SliceThickness), "1.25");
  EXPECT_EQ(get_string(ds, DCM_RescaleIntercept), "-1000");
  EXPECT_EQ(get_string(ds, DCM_RescaleSlope), "2");
  EXPECT_EQ(get_string(ds, DCM_ConvolutionKernel), "B30f");
  EXPECT_EQ(get_string(ds, DCM_GantryDetectorTilt), "-12.5");
  EXPECT_EQ(get_string(ds, DCM_PhotometricInterpretation), "MONOCHROME2");
  EXPECT_EQ(get_string(ds, DCM_SliceLocation), "<absent>");  // optional, not set
  EXPECT_EQ(get_string(ds, DCM_PixelPaddingValue), "<absent>");

  Uint16 value = 0;
  ASSERT_TRUE(ds.findAndGetUint16(DCM_Rows, value).good());
  EXPECT_EQ(value, 12);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_Columns, value).good());
  EXPECT_EQ(value, 10);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_BitsAllocated, value).good());
  EXPECT_EQ(value, 16);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_BitsStored, value).good());
  EXPECT_EQ(value, 12);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_HighBit, value).good());
  EXPECT_EQ(value, 11);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_PixelRepresentation, value).good());
  EXPECT_EQ(value, 0);
  ASSERT_TRUE(ds.findAndGetUint16(DCM_SamplesPerPixel, value).good());
  EXPECT_EQ(value, 1);
  EXPECT_EQ(get_pixels(ds), spec.pixels);

  DcmMetaInfo& meta = *file->getMetaInfo();
  EXPECT_EQ(get_string(meta, DCM_TransferSyntaxUID), "1.2.840.10008.1.2.1");
  EXPECT_EQ(get_string(meta, DCM_MediaStorageSOPClassUID), spec.sop_class_uid);
  EXPECT_EQ(get_string(meta, DCM_MediaStorageSOPInstanceUID), spec.sop_instance_uid);
  EXPECT_EQ(get_string(meta, DCM_ImplementationClassUID), kImplementationClassUid);
  EXPECT_EQ(get_string(meta, DCM_ImplementationVersionName), kImplementationVersionName);
}

TEST_F(CtWriterTest, DefaultSpecIsZeroFilledSixteenBySixteen) {
  write_ct_slice(CtSliceSpec{}, dir_ / "default.dcm");
  auto file = load(dir_ / "default.dcm");
  ASSERT_TRUE(file);
  EXPECT_EQ(get_pixels(*file->getDataset()), std::vector<std::uint16_t>(256, 0));
}

// Each transfer syntax: the meta header names it, and the pixels decode to what was written.
class TransferSyntaxTest : public CtWriterTest,
                           public ::testing::WithParamInterface<TransferSyntax> {};

TEST_P(TransferSyntaxTest, PixelsRoundTrip) {
  CtSliceSpec spec;
  spec.transfer_syntax = GetParam();
  spec.pixels = test_pattern(16, 16);
  const fs::path path = dir_ / "slice.dcm";
  write_ct_slice(spec, path);

  auto file = load(path);
  ASSERT_TRUE(file);
  EXPECT_EQ(get_string(*file->getMetaInfo(), DCM_TransferSyntaxUID), to_uid(GetParam()));
  EXPECT_EQ(DcmXfer(file->getDataset()->getOriginalXfer()).getXferID(),
            std::string(to_uid(GetParam())));
  DcmDataset& ds = *file->getDataset();
  // Lossless: no new identity for the image.
  EXPECT_EQ(get_string(ds, DCM_SOPInstanceUID), spec.sop_instance_uid);
  EXPECT_EQ(get_string(ds, DCM_ImageType), spec.image_type);
  EXPECT_EQ(get_pixels(ds), spec.pixels);
}

TEST_P(TransferSyntaxTest, SameSpecGivesSameBytes) {
  CtSliceSpec spec;
  spec.transfer_syntax = GetParam();
  spec.pixels = test_pattern(16, 16);
  write_ct_slice(spec, dir_ / "a.dcm");
  write_ct_slice(spec, dir_ / "b.dcm");
  const std::string a = read_file(dir_ / "a.dcm");
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a, read_file(dir_ / "b.dcm"));
}

INSTANTIATE_TEST_SUITE_P(
    AllSyntaxes, TransferSyntaxTest,
    ::testing::Values(TransferSyntax::implicit_little, TransferSyntax::explicit_little,
                      TransferSyntax::explicit_big, TransferSyntax::deflated_little,
                      TransferSyntax::jpeg_lossless, TransferSyntax::jpeg_ls_lossless,
                      TransferSyntax::rle_lossless),
    [](const ::testing::TestParamInfo<TransferSyntax>& syntax) {
      switch (syntax.param) {
        case TransferSyntax::implicit_little:
          return "implicit_little";
        case TransferSyntax::explicit_little:
          return "explicit_little";
        case TransferSyntax::explicit_big:
          return "explicit_big";
        case TransferSyntax::deflated_little:
          return "deflated_little";
        case TransferSyntax::jpeg_lossless:
          return "jpeg_lossless";
        case TransferSyntax::jpeg_ls_lossless:
          return "jpeg_ls_lossless";
        case TransferSyntax::rle_lossless:
          return "rle_lossless";
      }
      return "unknown";
    });

TEST_F(CtWriterTest, Part10FileStartsWithZeroPreambleAndDicm) {
  write_ct_slice(CtSliceSpec{}, dir_ / "part10.dcm");
  const std::string bytes = read_file(dir_ / "part10.dcm");
  ASSERT_GT(bytes.size(), 132u);
  EXPECT_EQ(bytes.substr(0, 128), std::string(128, '\0'));
  EXPECT_EQ(bytes.substr(128, 4), "DICM");
  EXPECT_EQ(bytes.substr(132, 4), std::string("\x02\x00\x00\x00", 4));  // (0002,0000)
}

TEST_F(CtWriterTest, NoPreambleStartsWithTheMetaHeaderAndStillReads) {
  CtSliceSpec spec;
  spec.pixels = test_pattern(16, 16);
  write_ct_slice(spec, dir_ / "part10.dcm");
  spec.container = Container::no_preamble;
  write_ct_slice(spec, dir_ / "no_preamble.dcm");

  const std::string part10 = read_file(dir_ / "part10.dcm");
  const std::string bare = read_file(dir_ / "no_preamble.dcm");
  EXPECT_EQ(bare, part10.substr(132));
  auto file = load(dir_ / "no_preamble.dcm");
  ASSERT_TRUE(file);
  EXPECT_EQ(get_string(*file->getMetaInfo(), DCM_TransferSyntaxUID), "1.2.840.10008.1.2.1");
  EXPECT_EQ(get_pixels(*file->getDataset()), spec.pixels);
}

TEST_F(CtWriterTest, DatasetOnlyHasNoMetaHeader) {
  CtSliceSpec spec;
  spec.transfer_syntax = TransferSyntax::implicit_little;
  spec.container = Container::dataset_only;
  spec.pixels = test_pattern(16, 16);
  write_ct_slice(spec, dir_ / "dataset.dcm");

  const std::string bytes = read_file(dir_ / "dataset.dcm");
  // Implicit VR: the first element is (0008,0008) ImageType, tag then a 32-bit length.
  EXPECT_EQ(bytes.substr(0, 4), std::string("\x08\x00\x08\x00", 4));
  auto file = load(dir_ / "dataset.dcm");
  ASSERT_TRUE(file);
  EXPECT_EQ(get_string(*file->getMetaInfo(), DCM_TransferSyntaxUID), "<absent>");
  EXPECT_EQ(get_string(*file->getDataset(), DCM_Modality), "CT");
  EXPECT_EQ(get_pixels(*file->getDataset()), spec.pixels);
}

TEST_F(CtWriterTest, BrokenValuesAreWrittenVerbatim) {
  CtSliceSpec spec;
  spec.pixel_spacing = "NaN\\-1";
  spec.image_position_patient = "inf\\0";  // also one value short
  spec.image_orientation_patient = "0\\0\\0\\0\\0\\0";
  spec.rescale_slope = "0";
  spec.slice_thickness = "";
  spec.instance_number = "1.5";
  spec.modality = "MR";
  spec.bits_stored = 17;  // more than allocated
  spec.high_bit = 3;
  write_ct_slice(spec, dir_ / "broken.dcm");

  auto file = load(dir_ / "broken.dcm");
  ASSERT_TRUE(file);
  DcmDataset& ds = *file->getDataset();
  EXPECT_EQ(get_string(ds, DCM_PixelSpacing), "NaN\\-1");
  EXPECT_EQ(get_string(ds, DCM_ImagePositionPatient), "inf\\0");
  EXPECT_EQ(get_string(ds, DCM_ImageOrientationPatient), "0\\0\\0\\0\\0\\0");
  EXPECT_EQ(get_string(ds, DCM_RescaleSlope), "0");
  EXPECT_EQ(get_string(ds, DCM_SliceThickness), "");  // present, empty
  EXPECT_EQ(get_string(ds, DCM_InstanceNumber), "1.5");
  EXPECT_EQ(get_string(ds, DCM_Modality), "MR");
  Uint16 value = 0;
  ASSERT_TRUE(ds.findAndGetUint16(DCM_BitsStored, value).good());
  EXPECT_EQ(value, 17);
}

TEST_F(CtWriterTest, ExtraOverridesAndOmitRemoves) {
  CtSliceSpec spec;
  spec.extra = {{{0x0018, 0x1120}, "18.5"},  // GantryDetectorTilt
                {{0x0008, 0x0060}, "OT"},    // overrides Modality
                {{0x0008, 0x0008}, "DERIVED\\SECONDARY\\LOCALIZER"}};
  spec.omit = {kImagePositionPatientTag, kPixelDataTag, {0x0020, 0x0052}};
  write_ct_slice(spec, dir_ / "edited.dcm");

  auto file = load(dir_ / "edited.dcm");
  ASSERT_TRUE(file);
  DcmDataset& ds = *file->getDataset();
  EXPECT_EQ(get_string(ds, DCM_GantryDetectorTilt), "18.5");
  EXPECT_EQ(get_string(ds, DCM_Modality), "OT");
  EXPECT_EQ(get_string(ds, DCM_ImageType), "DERIVED\\SECONDARY\\LOCALIZER");
  EXPECT_FALSE(ds.tagExists(DCM_ImagePositionPatient));
  EXPECT_FALSE(ds.tagExists(DCM_PixelData));
  EXPECT_FALSE(ds.tagExists(DCM_FrameOfReferenceUID));
  EXPECT_TRUE(ds.tagExists(DCM_ImageOrientationPatient));
}

TEST_F(CtWriterTest, TruncatesToTheGivenSize) {
  CtSliceSpec spec;
  spec.pixels = test_pattern(16, 16);
  write_ct_slice(spec, dir_ / "whole.dcm");
  spec.truncate_to_bytes = 1000;
  write_ct_slice(spec, dir_ / "cut.dcm");
  spec.truncate_to_bytes = 1'000'000;  // longer than the file: no change
  write_ct_slice(spec, dir_ / "uncut.dcm");

  const std::string whole = read_file(dir_ / "whole.dcm");
  ASSERT_GT(whole.size(), 1000u);
  EXPECT_EQ(read_file(dir_ / "cut.dcm"), whole.substr(0, 1000));
  EXPECT_EQ(read_file(dir_ / "uncut.dcm"), whole);
}

TEST_F(CtWriterTest, SignedPixelsAndPaddingValue) {
  CtSliceSpec spec;
  spec.rows = 2;
  spec.columns = 3;
  spec.bits_stored = 16;
  spec.high_bit = 15;
  spec.pixel_representation = 1;
  spec.rescale_intercept = "0";
  spec.pixel_padding_value = -2000;
  for (const int v : {-2000, -1000, 0, 40, 1000, 3000}) spec.pixels.push_back(to_pixel_word(v));
  write_ct_slice(spec, dir_ / "signed.dcm");

  auto file = load(dir_ / "signed.dcm");
  ASSERT_TRUE(file);
  DcmDataset& ds = *file->getDataset();
  DcmElement* padding = nullptr;
  ASSERT_TRUE(ds.findAndGetElement(DCM_PixelPaddingValue, padding).good());
  EXPECT_EQ(padding->getVR(), EVR_SS);
  Sint16 padding_value = 0;
  ASSERT_TRUE(ds.findAndGetSint16(DCM_PixelPaddingValue, padding_value).good());
  EXPECT_EQ(padding_value, -2000);
  const std::vector<std::uint16_t> words = get_pixels(ds);
  ASSERT_EQ(words.size(), 6u);
  EXPECT_EQ(static_cast<std::int16_t>(words[0]), -2000);
  EXPECT_EQ(static_cast<std::int16_t>(words[5]), 3000);
}

TEST_F(CtWriterTest, UnsignedPaddingValueIsUs) {
  CtSliceSpec spec;
  spec.pixel_padding_value = 0;
  write_ct_slice(spec, dir_ / "padding.dcm");
  auto file = load(dir_ / "padding.dcm");
  ASSERT_TRUE(file);
  DcmElement* padding = nullptr;
  ASSERT_TRUE(file->getDataset()->findAndGetElement(DCM_PixelPaddingValue, padding).good());
  EXPECT_EQ(padding->getVR(), EVR_US);
}

TEST_F(CtWriterTest, EightBitPixelsAreOneBytePerSample) {
  CtSliceSpec spec;
  spec.rows = 4;
  spec.columns = 4;
  spec.bits_allocated = 8;
  spec.bits_stored = 8;
  spec.high_bit = 7;
  for (int n = 0; n < 16; ++n) spec.pixels.push_back(static_cast<std::uint16_t>(n * 16));
  write_ct_slice(spec, dir_ / "eight.dcm");

  auto file = load(dir_ / "eight.dcm");
  ASSERT_TRUE(file);
  const Uint8* bytes = nullptr;
  unsigned long count = 0;
  ASSERT_TRUE(file->getDataset()->findAndGetUint8Array(DCM_PixelData, bytes, &count).good());
  ASSERT_EQ(count, 16u);
  EXPECT_EQ(bytes[15], 240);
}

TEST_F(CtWriterTest, FailuresThrowNamingTheFile) {
  const fs::path missing = dir_ / "no_such_dir" / "slice.dcm";
  try {
    write_ct_slice(CtSliceSpec{}, missing);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(missing.string()), std::string::npos) << error.what();
  }

  // An encoder cannot compress a PixelData shorter than rows × columns.
  CtSliceSpec spec;
  spec.transfer_syntax = TransferSyntax::jpeg_lossless;
  spec.pixels.assign(10, 0);
  EXPECT_THROW(write_ct_slice(spec, dir_ / "bad_jpeg.dcm"), std::runtime_error);
}

TEST_F(CtWriterTest, AxialSeriesInThreeLines) {
  SeriesLayout layout;
  layout.hu = [](int i, int j, int k) { return i + j + k > 12 ? 1000.0 : -1000.0; };
  const auto paths = write_series(make_axial_series(layout), dir_);

  ASSERT_EQ(paths.size(), 8u);
  EXPECT_EQ(paths[3].filename(), "slice_0003.dcm");
  auto file = load(paths[3]);
  ASSERT_TRUE(file);
  DcmDataset& ds = *file->getDataset();
  EXPECT_EQ(get_string(ds, DCM_ImagePositionPatient), "0\\0\\3");
  EXPECT_EQ(get_string(ds, DCM_InstanceNumber), "4");
  const std::vector<std::uint16_t> pixels = get_pixels(ds);
  ASSERT_EQ(pixels.size(), 256u);
  EXPECT_EQ(pixels[0], 24);               // −1000 HU at (0, 0, 3)
  EXPECT_EQ(pixels[15 + 16 * 15], 2024);  // +1000 HU at (15, 15, 3)
  EXPECT_EQ(pixels[9 + 16 * 0], 24);      // 9 + 0 + 3 = 12: not > 12
  EXPECT_EQ(pixels[10 + 16 * 0], 2024);
}

TEST(MakeAxialSeries, GeometryAndIdentity) {
  SeriesLayout layout;
  layout.uid_seed = "geometry";
  layout.columns = 4;
  layout.rows = 3;
  layout.slices = 5;
  layout.pixel_spacing = {0.5, 0.25};
  layout.slice_spacing = 2.5;
  layout.origin = {-10, 20, 30};
  layout.orientation = {1, 0, 0, 0, 0, -1};  // coronal: normal = row × column = (0, 1, 0)
  layout.stored_value = [](int i, int j, int k) { return 100 * k + 10 * j + i; };
  const std::vector<CtSliceSpec> specs = make_axial_series(layout);

  ASSERT_EQ(specs.size(), 5u);
  EXPECT_EQ(specs[0].image_position_patient, "-10\\20\\30");
  EXPECT_EQ(specs[4].image_position_patient, "-10\\30\\30");
  EXPECT_EQ(specs[4].slice_location, "30");
  EXPECT_EQ(specs[4].image_orientation_patient, "1\\0\\0\\0\\0\\-1");
  EXPECT_EQ(specs[4].pixel_spacing, "0.5\\0.25");
  EXPECT_EQ(specs[4].slice_thickness, "2.5");
  EXPECT_EQ(specs[4].spacing_between_slices, "2.5");
  EXPECT_EQ(specs[4].instance_number, "5");
  EXPECT_EQ(specs[4].rows, 3);
  EXPECT_EQ(specs[4].columns, 4);
  EXPECT_EQ(specs[4].pixels.size(), 12u);
  EXPECT_EQ(specs[4].pixels[1 + 4 * 2], 421);  // i = 1, j = 2, k = 4
  EXPECT_EQ(specs[0].series_instance_uid, specs[4].series_instance_uid);
  EXPECT_EQ(specs[0].study_instance_uid, specs[4].study_instance_uid);
  EXPECT_EQ(specs[0].frame_of_reference_uid, specs[4].frame_of_reference_uid);
  EXPECT_NE(specs[0].sop_instance_uid, specs[4].sop_instance_uid);
  EXPECT_NE(specs[0].series_instance_uid, specs[0].study_instance_uid);
  EXPECT_EQ(specs[0].series_instance_uid, make_uid("geometry/series"));

  layout.uid_seed = "other";
  EXPECT_NE(make_axial_series(layout)[0].series_instance_uid, specs[0].series_instance_uid);
}

TEST(MakeAxialSeries, TiltedStackIsSheared) {
  SeriesLayout layout;
  layout.slices = 3;
  layout.slice_spacing = 2;
  layout.slice_step = Vec3{0, 0.5, 2};  // the table advances; a tilted gantry shifts y per slice
  const std::vector<CtSliceSpec> specs = make_axial_series(layout);
  ASSERT_EQ(specs.size(), 3u);
  EXPECT_EQ(specs[2].image_position_patient, "0\\1\\4");
  EXPECT_EQ(specs[2].image_orientation_patient, "1\\0\\0\\0\\1\\0");
  EXPECT_EQ(specs[2].slice_location, "4");
}

TEST(StoredFromHu, RoundsAndClampsToTheStoredRange) {
  // 12-bit unsigned, intercept −1024: the sample series' encoding.
  EXPECT_EQ(stored_from_hu(-1024, -1024, 1, 12, 0), 0);
  EXPECT_EQ(stored_from_hu(-2000, -1024, 1, 12, 0), 0);
  EXPECT_EQ(stored_from_hu(40, -1024, 1, 12, 0), 1064);
  EXPECT_EQ(stored_from_hu(40.5, -1024, 1, 12, 0), 1065);  // ties away from zero
  EXPECT_EQ(stored_from_hu(40.49, -1024, 1, 12, 0), 1064);
  EXPECT_EQ(stored_from_hu(3071, -1024, 1, 12, 0), 4095);
  EXPECT_EQ(stored_from_hu(5000, -1024, 1, 12, 0), 4095);
  // 16-bit signed, intercept 0, slope 2.
  EXPECT_EQ(stored_from_hu(-1000, 0, 2, 16, 1), -500);
  EXPECT_EQ(stored_from_hu(-1e6, 0, 1, 16, 1), -32768);
  EXPECT_EQ(stored_from_hu(1e6, 0, 1, 16, 1), 32767);
  EXPECT_EQ(stored_from_hu(std::nan(""), 0, 1, 16, 1), 0);
  EXPECT_EQ(to_pixel_word(-1), 0xFFFF);
  EXPECT_EQ(to_pixel_word(-32768), 0x8000);
}

TEST(MakeUid, IsValidStableAndDistinct) {
  // FNV-1a of the empty string is its offset basis.
  EXPECT_EQ(make_uid(""), "1.2.826.0.1.3680043.10.1234.14695981039346656037");
  EXPECT_EQ(make_uid("a"), make_uid("a"));
  EXPECT_NE(make_uid("slice/1"), make_uid("slice/2"));
  for (const char* key : {"", "a", "slice/1", "a much longer key with spaces and / slashes"}) {
    const std::string uid = make_uid(key);
    EXPECT_LE(uid.size(), 64u) << uid;
    EXPECT_EQ(uid.rfind(kUidRoot, 0), 0u) << uid;
    EXPECT_TRUE(std::all_of(uid.begin(), uid.end(), [](char c) {
      return c == '.' || std::isdigit(static_cast<unsigned char>(c));
    })) << uid;
    EXPECT_EQ(uid.find(".0", kUidRoot.size() - 1), std::string::npos) << "leading zero: " << uid;
  }
}

TEST(FormatDs, ShortestTextThatFitsSixteenCharacters) {
  EXPECT_EQ(format_ds(0.0), "0");
  EXPECT_EQ(format_ds(-0.0), "0");
  EXPECT_EQ(format_ds(1.5), "1.5");
  EXPECT_EQ(format_ds(-95.25), "-95.25");
  EXPECT_EQ(format_ds(-1024), "-1024");
  EXPECT_EQ(format_ds(0.1 + 0.2), "0.3");  // 0.30000000000000004 does not fit
  EXPECT_EQ(format_ds(1e-20), "1e-20");
  for (const double v :
       {1.0 / 3, -2.0 / 3, 123456789.123456789, -1.2345678901234567e-300, 6.02214076e23}) {
    const std::string text = format_ds(v);
    EXPECT_LE(text.size(), 16u) << text;
    EXPECT_NEAR(std::stod(text), v, std::abs(v) * 1e-9) << text;
  }
  const double position[3] = {-95.25, 0, 12.5};
  EXPECT_EQ(format_ds(position), "-95.25\\0\\12.5");
}

}  // namespace
}  // namespace typemerge::ct_writer
