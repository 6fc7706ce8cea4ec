// NRRD reader: files written from the format's specification in the test (raw and gzip,
// attached and detached, both byte orders, every type, each space), Slicer's .seg.nrrd keys
// and layers, refusals; then the shared Slicer label maps.
#include "nrrd/nrrd_reader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/scratch_files.h"
#include "support/test_data.h"
#include "support/volume_file_writers.h"

namespace typemerge::nrrd {
namespace {

namespace fs = std::filesystem;

// Sample v as a float, whatever the storage.
float sample(const core::Volume& volume, std::size_t v) {
  return volume.visit([&](const auto* samples) { return static_cast<float>(samples[v]); });
}

std::vector<double> ramp(int n) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(i);
  return v;
}

const std::string kGeometry =
    "dimension: 3\nsizes: 4 3 2\nspace: right-anterior-superior\n"
    "space directions: (0.5,0,0) (0,0.75,0) (0,0,2)\nspace origin: (10,-20,30)\n";

TEST(NrrdReader, RawRasToLps) {
  const auto bytes = test::nrrd_bytes("type: short\n" + kGeometry +
                                          "encoding: raw\nendian: little\ncontent: PATIENT^NAME\n"
                                          "# a comment\nsome key:=some value\n",
                                      test::raw_samples<std::int16_t>(ramp(24)), false);
  const NrrdImage image = decode_nrrd(bytes);
  ASSERT_EQ(image.layers.size(), 1u);
  const core::Volume& v = image.layers[0];
  EXPECT_EQ(v.size(), (core::VolumeSize{4, 3, 2}));
  EXPECT_FLOAT_EQ(v.at(3, 2, 1), 23.0f);
  EXPECT_DOUBLE_EQ(v.geometry().origin[0], -10);
  EXPECT_DOUBLE_EQ(v.geometry().origin[1], 20);
  EXPECT_DOUBLE_EQ(v.geometry().axes[0][0], -0.5);
  EXPECT_DOUBLE_EQ(v.geometry().axes[1][1], -0.75);
  EXPECT_FALSE(image.header.segmentation);
  EXPECT_TRUE(image.warnings.empty());
}

TEST(NrrdReader, EveryTypeBothByteOrdersGzip) {
  struct Case {
    const char* name;
    test::FileBytes (*raw)(const std::vector<double>&, bool);
  };
  const Case cases[] = {{"int8", test::raw_samples<std::int8_t>},
                        {"uchar", test::raw_samples<std::uint8_t>},
                        {"short", test::raw_samples<std::int16_t>},
                        {"unsigned short", test::raw_samples<std::uint16_t>},
                        {"int", test::raw_samples<std::int32_t>},
                        {"uint32_t", test::raw_samples<std::uint32_t>},
                        {"long long", test::raw_samples<std::int64_t>},
                        {"ulonglong", test::raw_samples<std::uint64_t>},
                        {"float", test::raw_samples<float>},
                        {"double", test::raw_samples<double>}};
  for (const Case& c : cases) {
    for (bool big : {false, true}) {
      for (bool gzip : {false, true}) {
        const std::string header = std::string("type: ") + c.name + "\n" + kGeometry +
                                   "encoding: " + (gzip ? "gzip" : "raw") +
                                   "\nendian: " + (big ? "big" : "little") + "\n";
        const NrrdImage image = decode_nrrd(test::nrrd_bytes(header, c.raw(ramp(24), big), gzip));
        // Integer types (values 0…23, within int16) load as int16, float types as float.
        const bool integer = std::string(c.name) != "float" && std::string(c.name) != "double";
        EXPECT_EQ(image.layers[0].holds_int16(), integer) << c.name;
        for (int i = 0; i < 24; ++i) {
          ASSERT_FLOAT_EQ(sample(image.layers[0], static_cast<std::size_t>(i)), float(i))
              << c.name << (big ? " big" : " little") << (gzip ? " gzip" : " raw");
        }
      }
    }
  }
}

// Values beyond int16 (an unsigned short of 40000, an int of −40000) stay float, per layer.
TEST(NrrdReader, ValuesBeyondInt16StayFloat) {
  std::vector<double> values = ramp(24);
  values[17] = 40000;
  const NrrdImage wide = decode_nrrd(test::nrrd_bytes(
      "type: unsigned short\n" + kGeometry + "encoding: raw\nendian: little\n",
      test::raw_samples<std::uint16_t>(values), false));
  EXPECT_FALSE(wide.layers[0].holds_int16());
  EXPECT_EQ(sample(wide.layers[0], 17), 40000.0f);
  values[17] = -40000;
  const NrrdImage negative = decode_nrrd(test::nrrd_bytes(
      "type: int\n" + kGeometry + "encoding: raw\nendian: big\n",
      test::raw_samples<std::int32_t>(values, true), false));
  EXPECT_FALSE(negative.layers[0].holds_int16());
  EXPECT_EQ(sample(negative.layers[0], 17), -40000.0f);
  EXPECT_EQ(negative.values.min, -40000.0f);
  values[17] = -32768;
  const NrrdImage fits = decode_nrrd(test::nrrd_bytes(
      "type: int\n" + kGeometry + "encoding: raw\nendian: big\n",
      test::raw_samples<std::int32_t>(values, true), false));
  EXPECT_TRUE(fits.layers[0].holds_int16());
  EXPECT_EQ(sample(fits.layers[0], 17), -32768.0f);
  EXPECT_EQ(fits.values.min, -32768.0f);
  EXPECT_EQ(fits.values.max, 23.0f);
}

TEST(NrrdReader, DetachedHeaderWithByteSkip) {
  const fs::path dir = test::fresh_dir("nhdr");
  {
    std::ofstream h(dir / "v.nhdr");
    h << "NRRD0004\ntype: float\n"
      << kGeometry << "encoding: raw\nendian: little\nbyte skip: -1\ndata file: v.raw\n";
  }
  test::FileBytes data(7, 0xee);  // junk before the samples
  const auto samples = test::raw_samples<float>(ramp(24));
  data.insert(data.end(), samples.begin(), samples.end());
  test::write_bytes(dir / "v.raw", data, false);
  const NrrdImage image = read_nrrd(dir / "v.nhdr");
  EXPECT_FLOAT_EQ(image.layers[0].at(2, 1, 1), 18.0f);
  EXPECT_EQ(read_nrrd_header(dir / "v.nhdr").size, (core::VolumeSize{4, 3, 2}));
  fs::remove_all(dir);
}

TEST(NrrdReader, SpacesAndSpacings) {
  auto origin_x = [](const std::string& space) {
    const std::string header = "type: uchar\ndimension: 3\nsizes: 4 3 2\nspace: " + space +
                               "\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
                               "space origin: (5,6,7)\nencoding: raw\n";
    const NrrdImage image =
        decode_nrrd(test::nrrd_bytes(header, test::raw_samples<std::uint8_t>(ramp(24)), false));
    return std::array<double, 2>{image.layers[0].geometry().origin[0],
                                 image.layers[0].geometry().origin[1]};
  };
  EXPECT_EQ(origin_x("left-posterior-superior"), (std::array<double, 2>{5, 6}));
  EXPECT_EQ(origin_x("LPS"), (std::array<double, 2>{5, 6}));
  EXPECT_EQ(origin_x("RAS"), (std::array<double, 2>{-5, -6}));
  EXPECT_EQ(origin_x("left-anterior-superior"), (std::array<double, 2>{5, -6}));
  const NrrdImage spaced = decode_nrrd(test::nrrd_bytes(
      "type: uchar\ndimension: 3\nsizes: 4 3 2\nspacings: 0.5 0.5 3\nencoding: raw\n",
      test::raw_samples<std::uint8_t>(ramp(24)), false));
  EXPECT_DOUBLE_EQ(spaced.layers[0].geometry().spacing(2), 3);
  EXPECT_EQ(spaced.warnings.size(), 1u);
}

TEST(NrrdReader, SlicerLayeredSegmentation) {
  // Two layers (list axis first), three segments: two in layer 0, one overlapping in layer 1.
  std::vector<double> values;
  for (int v = 0; v < 24; ++v) {
    values.push_back(v < 8 ? 1 : v < 16 ? 2 : 0);  // layer 0
    values.push_back(v >= 4 && v < 12 ? 1 : 0);    // layer 1
  }
  const std::string header =
      "type: unsigned char\ndimension: 4\nsizes: 2 4 3 2\nkinds: list domain domain domain\n"
      "space: left-posterior-superior\n"
      "space directions: none (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\nencoding: gzip\n"
      "Segment0_Name:=liver\nSegment0_Color:=1 0 0\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
      "Segment0_Tags:=PATIENT^NAME\n"
      "Segment1_Name:=spine\nSegment1_Color:=0 0.5 1\nSegment1_LabelValue:=2\nSegment1_Layer:=0\n"
      "Segment2_Name:=tumour\nSegment2_Color:=0 1 0\nSegment2_LabelValue:=1\nSegment2_Layer:=1\n";
  NrrdImage image =
      decode_nrrd(test::nrrd_bytes(header, test::raw_samples<std::uint8_t>(values), true));
  EXPECT_TRUE(image.header.segmentation);
  ASSERT_EQ(image.layers.size(), 2u);
  EXPECT_FLOAT_EQ(sample(image.layers[0], 9), 2.0f);
  EXPECT_FLOAT_EQ(sample(image.layers[1], 9), 1.0f);
  const core::LabelVolume labels = to_label_volume(std::move(image));
  ASSERT_EQ(labels.segments.size(), 3u);
  EXPECT_EQ(labels.segments[1].name, "spine");
  EXPECT_EQ(labels.segments[1].label, 2);
  EXPECT_EQ(labels.segments[2].layer, 1u);
  EXPECT_EQ(labels.segments[1].srgb, (std::array<std::uint8_t, 3>{0, 128, 255}));
}

void expect_refused(const std::string& header, const test::FileBytes& data, bool gzip,
                    const std::string& words) {
  try {
    decode_nrrd(test::nrrd_bytes(header, data, gzip));
    ADD_FAILURE() << "accepted; expected '" << words << "'";
  } catch (const ReadError& error) {
    EXPECT_NE(std::string(error.what()).find(words), std::string::npos) << error.what();
  }
}

TEST(NrrdReader, Refusals) {
  const auto data = test::raw_samples<std::uint8_t>(ramp(24));
  const std::string base = "type: uchar\n" + kGeometry;
  expect_refused(base + "encoding: raw\n", test::FileBytes(data.begin(), data.begin() + 10), false,
                 "truncated");
  expect_refused(base + "encoding: bzip2\n", data, false, "not supported");
  expect_refused(base + "encoding: ascii\n", data, false, "not supported");
  expect_refused("type: uchar\ndimension: 3\nsizes: 4000000 4000000 4000000\nencoding: raw\n", data,
                 false, "");
  expect_refused(
      "type: uchar\ndimension: 3\nsizes: 4 3 2\nspace: RAS\n"
      "space directions: (1,0,0) (0,1,0) (0,0,nan)\nencoding: raw\n",
      data, false, "finite");
  expect_refused(
      "type: uchar\ndimension: 3\nsizes: 4 3 2\nspace: RAS\n"
      "space directions: (1,0,0) (1,0,0) (0,0,1)\nencoding: raw\n",
      data, false, "singular");
  expect_refused("type: block\n" + kGeometry + "encoding: raw\n", data, false, "type");
  expect_refused("type: uchar\ndimension: 2\nsizes: 4 6\nencoding: raw\n", data, false,
                 "dimension");
  auto gz = test::gzip_bytes(data);
  gz.resize(gz.size() / 2);
  try {
    auto text = test::nrrd_bytes(base + "encoding: gzip\n", {}, false);
    text.insert(text.end(), gz.begin(), gz.end());
    decode_nrrd(text);
    ADD_FAILURE() << "truncated gzip accepted";
  } catch (const ReadError&) {
  }
  EXPECT_THROW(decode_nrrd(test::FileBytes{'N', 'R', 'R', 'D'}), ReadError);
  ReadOptions small;
  small.max_volume_bytes = 16;
  EXPECT_THROW(decode_nrrd(test::nrrd_bytes(base + "encoding: raw\n", data, false), small),
               ReadError);
}

TEST(NrrdRealData, SlicerLabelMaps) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path dir = data / "seg" / "dcmqi";
  for (const char* name :
       {"liver_seg.nrrd", "heart_seg.nrrd", "liver_spine_seg.nrrd", "23x38x3/nrrd/label.nrrd"}) {
    if (!fs::exists(dir / name)) GTEST_SKIP() << (dir / name) << " absent";
    const NrrdImage image = read_nrrd(dir / name);
    ASSERT_EQ(image.layers.size(), 1u) << name;
    EXPECT_TRUE(image.values.all_integer) << name;
    EXPECT_GT(image.values.max, 0) << name;
    EXPECT_LT(image.layers[0].geometry().determinant(), 1e6) << name;
  }
  const NrrdImage two = read_nrrd(dir / "liver_spine_seg.nrrd");
  EXPECT_EQ(two.layers[0].size(), (core::VolumeSize{512, 512, 3}));
}

}  // namespace
}  // namespace typemerge::nrrd
