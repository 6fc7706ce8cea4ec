// NIfTI reader: files written byte by byte from the specification (support/volume_file_writers.h)
// for every data type, both versions, both byte orders, gzip, each geometry source and each
// refusal; then the shared real NIfTI files.
#include "nifti/nifti_reader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "support/scratch_files.h"
#include "support/test_data.h"
#include "support/volume_file_writers.h"

namespace typemerge::nifti {
namespace {

namespace fs = std::filesystem;
using test::NiftiSpec;

NiftiSpec small_spec(int datatype = test::kDtFloat32) {
  NiftiSpec s;
  s.dim = {3, 4, 3, 2, 1, 1, 1, 1};
  s.datatype = datatype;
  for (int v = 0; v < 24; ++v) s.values.push_back(v);
  s.srow = {{{-0.5, 0, 0, 10}, {0, 0.75, 0, -20}, {0, 0, 2, 30}}};
  return s;
}

NiftiImage decode(const NiftiSpec& spec) {
  const auto bytes = test::nifti_bytes(spec);
  return decode_nifti(bytes);
}

// Sample v as a float, whatever the storage.
float sample(const core::Volume& volume, std::size_t v) {
  return volume.visit([&](const auto* samples) { return static_cast<float>(samples[v]); });
}

TEST(NiftiReader, SformFloatValuesAndLpsGeometry) {
  const NiftiImage image = decode(small_spec());
  EXPECT_EQ(image.volume.size(), (core::VolumeSize{4, 3, 2}));
  EXPECT_EQ(image.header.geometry_source, "sform");
  EXPECT_FLOAT_EQ(image.volume.at(3, 2, 1), 23.0f);
  EXPECT_FLOAT_EQ(image.volume.at(1, 0, 0), 1.0f);
  const auto& g = image.volume.geometry();
  // RAS (x, y) negated: LPS.
  EXPECT_DOUBLE_EQ(g.origin[0], -10);
  EXPECT_DOUBLE_EQ(g.origin[1], 20);
  EXPECT_DOUBLE_EQ(g.origin[2], 30);
  EXPECT_DOUBLE_EQ(g.axes[0][0], 0.5);
  EXPECT_DOUBLE_EQ(g.axes[1][1], -0.75);
  EXPECT_DOUBLE_EQ(g.axes[2][2], 2);
  EXPECT_TRUE(image.values.all_integer);
  EXPECT_TRUE(image.warnings.empty());
}

TEST(NiftiReader, EveryIntegerAndFloatTypeWithScaling) {
  for (int type :
       {test::kDtUint8, test::kDtInt8, test::kDtInt16, test::kDtUint16, test::kDtInt32,
        test::kDtUint32, test::kDtInt64, test::kDtUint64, test::kDtFloat32, test::kDtFloat64}) {
    NiftiSpec spec = small_spec(type);
    spec.slope = 2;
    spec.inter = -1;
    const NiftiImage image = decode(spec);
    for (int v = 0; v < 24; ++v) {
      ASSERT_FLOAT_EQ(image.volume.samples()[static_cast<std::size_t>(v)], 2.0f * float(v) - 1.0f)
          << "type " << type;
    }
  }
  NiftiSpec negative = small_spec(test::kDtInt16);
  negative.values[5] = -1024;
  EXPECT_FLOAT_EQ(sample(decode(negative).volume, 5), -1024.0f);
}

TEST(NiftiReader, SlopeZeroMeansNoScaling) {
  NiftiSpec spec = small_spec(test::kDtInt16);
  spec.slope = 0;
  spec.inter = 100;
  EXPECT_FLOAT_EQ(sample(decode(spec).volume, 7), 7.0f);
}

// Integer values within int16 load as int16 samples (as a CT series does), anything else as
// floats; the values are the same either way.
TEST(NiftiReader, IntegerValuesWithinInt16LoadAsInt16) {
  struct Case {
    int datatype;
    double slope, inter;
    double extra;  // stored at sample 23
    bool int16;
  };
  const Case cases[] = {
      {test::kDtInt16, 0, 0, -32768, true},    // no scaling
      {test::kDtInt16, 1, -1024, 100, true},   // integer intercept
      {test::kDtUint8, 1, -1024, 255, true},   // decided by the type's range
      {test::kDtInt8, 0, 0, -128, true},
      {test::kDtUint16, 0, 0, 32767, true},    // decided by the data
      {test::kDtUint16, 0, 0, 32768, false},   // beyond int16
      {test::kDtInt32, 1, -1024, 33791, true},  // 33791 − 1024 = 32767
      {test::kDtInt32, 1, -1024, -31745, false},  // −32769
      {test::kDtUint64, 0, 0, 4000, true},
      {test::kDtInt16, 2, 0, 5, false},        // slope 2
      {test::kDtInt16, 1, 0.5, 5, false},      // fractional intercept
      {test::kDtInt16, 1, -40000, 5, false},   // intercept beyond the range
      {test::kDtFloat32, 0, 0, 5, false},      // float data stays float
      {test::kDtFloat64, 0, 0, 5, false},
  };
  for (const Case& c : cases) {
    for (const bool big_endian : {false, true}) {
      NiftiSpec spec = small_spec(c.datatype);
      spec.slope = c.slope;
      spec.inter = c.inter;
      spec.values[23] = c.extra;
      spec.big_endian = big_endian;
      const NiftiImage image = decode(spec);
      const double slope = c.slope == 0 ? 1 : c.slope, inter = c.slope == 0 ? 0 : c.inter;
      EXPECT_EQ(image.volume.holds_int16(), c.int16)
          << "type " << c.datatype << " extra " << c.extra << " slope " << c.slope;
      EXPECT_EQ(image.volume.sample_bytes(), 24u * (c.int16 ? 2 : 4));
      for (std::size_t v = 0; v < 24; ++v) {
        ASSERT_EQ(sample(image.volume, v),
                  static_cast<float>(slope * spec.values[v] + inter))
            << "type " << c.datatype << " sample " << v;
      }
      EXPECT_EQ(image.values.min, static_cast<float>(std::min(inter, slope * c.extra + inter)));
      EXPECT_EQ(image.values.max, static_cast<float>(std::max(slope * 22 + inter,
                                                              slope * c.extra + inter)));
      if (c.int16) EXPECT_TRUE(image.values.all_integer);
    }
  }
}

TEST(NiftiReader, QformWhenNoSform) {
  NiftiSpec spec = small_spec();
  spec.sform_code = 0;
  spec.qform_code = 1;
  spec.pixdim = {0.5, 0.75, 2};
  spec.qoffset = {1, 2, 3};
  spec.quatern = {0, 0, 1};  // 180° about z: i → -x, j → -y in RAS, so +x, +y in LPS
  const NiftiImage image = decode(spec);
  EXPECT_EQ(image.header.geometry_source, "qform");
  const auto& g = image.volume.geometry();
  EXPECT_NEAR(g.axes[0][0], 0.5, 1e-6);
  EXPECT_NEAR(g.axes[1][1], 0.75, 1e-6);
  EXPECT_NEAR(g.axes[2][2], 2, 1e-6);
  EXPECT_NEAR(g.origin[0], -1, 1e-6);
  EXPECT_NEAR(g.origin[1], -2, 1e-6);
  EXPECT_NEAR(g.origin[2], 3, 1e-6);
}

TEST(NiftiReader, PixelSpacingAloneWithAWarning) {
  NiftiSpec spec = small_spec();
  spec.sform_code = 0;
  spec.qform_code = 0;
  spec.pixdim = {0.5, 0.75, 2};
  const NiftiImage image = decode(spec);
  EXPECT_EQ(image.header.geometry_source, "pixel spacing");
  EXPECT_NEAR(image.volume.geometry().spacing(0), 0.5, 1e-6);
  EXPECT_NEAR(image.volume.geometry().spacing(2), 2, 1e-6);
  EXPECT_EQ(image.warnings.size(), 1u);
}

TEST(NiftiReader, Nifti2BigEndianGzipAndExtensions) {
  const fs::path dir = test::fresh_dir("nifti2");
  NiftiSpec spec = small_spec(test::kDtInt32);
  spec.version = 2;
  spec.big_endian = true;
  spec.extension = "a private extension";
  test::write_nifti(dir / "v.nii.gz", spec);
  const NiftiImage image = read_nifti(dir / "v.nii.gz");
  EXPECT_EQ(image.header.version, 2);
  EXPECT_TRUE(image.header.swap);
  EXPECT_FLOAT_EQ(image.volume.at(3, 2, 1), 23.0f);
  EXPECT_DOUBLE_EQ(image.volume.geometry().origin[0], -10);
  const NiftiHeader header = read_header(dir / "v.nii.gz");
  EXPECT_EQ(header.size, (core::VolumeSize{4, 3, 2}));
  fs::remove_all(dir);
}

TEST(NiftiReader, NonFiniteValuesBecomeZeroWithAWarning) {
  NiftiSpec spec = small_spec(test::kDtFloat32);
  spec.values[2] = std::nan("");
  spec.values[3] = 1e300;  // infinite as float
  const NiftiImage image = decode(spec);
  EXPECT_EQ(image.values.non_finite, 2u);
  EXPECT_EQ(image.volume.samples()[2], 0.0f);
  EXPECT_EQ(image.warnings.size(), 1u);
}

void expect_refused(const NiftiSpec& spec, const std::string& words) {
  try {
    decode(spec);
    ADD_FAILURE() << "accepted; expected a refusal with '" << words << "'";
  } catch (const ReadError& error) {
    EXPECT_NE(std::string(error.what()).find(words), std::string::npos) << error.what();
  }
}

TEST(NiftiReader, Refusals) {
  NiftiSpec four_d = small_spec();
  four_d.dim = {4, 2, 2, 2, 3, 1, 1, 1};
  four_d.values.resize(24);
  expect_refused(four_d, "4D");

  NiftiSpec beyond = small_spec();
  beyond.vox_offset = 100000;
  beyond.values.clear();
  expect_refused(beyond, "beyond the end");

  NiftiSpec truncated = small_spec();
  truncated.values.resize(10);
  expect_refused(truncated, "truncated");

  NiftiSpec overflow = small_spec();
  overflow.version = 2;
  overflow.dim = {3, std::int64_t{1} << 40, std::int64_t{1} << 40, std::int64_t{1} << 40, 1, 1, 1,
                  1};
  expect_refused(overflow, "overflow");

  NiftiSpec zero_dim = small_spec();
  zero_dim.dim = {3, 4, 0, 2, 1, 1, 1, 1};
  expect_refused(zero_dim, "dimension 2");

  NiftiSpec non_finite = small_spec();
  non_finite.srow[1][2] = std::nan("");
  expect_refused(non_finite, "not finite");

  NiftiSpec singular = small_spec();
  singular.srow[2] = {0, 0, 0, 5};
  expect_refused(singular, "singular");

  NiftiSpec complex = small_spec(test::kDtComplex64);
  expect_refused(complex, "not supported");

  auto bytes = test::nifti_bytes(small_spec());
  bytes.resize(200);
  EXPECT_THROW(decode_nifti(bytes), ReadError);
  bytes.assign(400, 0);
  EXPECT_THROW(decode_nifti(bytes), ReadError);
}

TEST(NiftiReader, DamagedGzipIsRefused) {
  const fs::path dir = test::fresh_dir("nifti_gz");
  const auto raw = test::nifti_bytes(small_spec());
  auto gz = test::gzip_bytes(raw);
  auto cut = gz;
  cut.resize(gz.size() / 2);
  test::write_bytes(dir / "cut.nii.gz", cut, false);
  EXPECT_THROW(read_nifti(dir / "cut.nii.gz"), ReadError);
  auto flipped = gz;
  for (std::size_t b = 20; b < flipped.size() - 8; b += 3) flipped[b] ^= 0x5a;
  test::write_bytes(dir / "bad.nii.gz", flipped, false);
  EXPECT_THROW(read_nifti(dir / "bad.nii.gz"), ReadError);
  auto crc = gz;
  crc[crc.size() - 6] ^= 0xff;  // the CRC of the member
  test::write_bytes(dir / "crc.nii.gz", crc, false);
  EXPECT_THROW(read_nifti(dir / "crc.nii.gz"), ReadError);
  fs::remove_all(dir);
}

// read_nifti decodes the data as it reads (inflates) it, in pieces of 1 MiB, where the header
// decides the storage: the same volume, summary and warnings as decoding the whole file, also
// with samples cut between pieces (odd vox_offset, 8-byte samples), for gzip and raw files;
// a file cut short is refused with the same reason. Where the values decide the storage, a
// value beyond int16 in a late piece turns the samples so far to floats.
TEST(NiftiReader, ReadingInPiecesGivesTheWholeFilesVolume) {
  const fs::path dir = test::fresh_dir("nifti_pieces");
  struct Case {
    int type;
    double inter;
    double late;  // stored at sample 480,000 (NaN: none)
  };
  for (const Case c : {Case{test::kDtInt16, 0, std::nan("")}, Case{test::kDtUint8, -1000, std::nan("")},
                       Case{test::kDtFloat64, 0, std::nan("")}, Case{test::kDtFloat32, 0, std::nan("")},
                       Case{test::kDtInt16, -1000, std::nan("")},  // the values decide: int16
                       Case{test::kDtInt16, -1000, -32000},         // the values decide: float
                       Case{test::kDtUint16, 0, 40000}}) {
    const int type = c.type;
    NiftiSpec spec;
    spec.dim = {3, 97, 83, 61, 1, 1, 1, 1};  // 491,111 samples: over 3.9 MB as float64
    spec.datatype = type;
    spec.vox_offset = 355;
    spec.inter = c.inter;
    spec.slope = c.inter != 0 ? 1 : 0;
    std::uint32_t state = 3;
    for (int v = 0; v < 97 * 83 * 61; ++v) {
      state = state * 1664525u + 1013904223u;
      const double value = static_cast<double>(state >> 24);  // 0…255
      spec.values.push_back(type == test::kDtFloat64 ? value / 7 : value);
    }
    if (type == test::kDtFloat32) spec.values[1000] = std::nan("");
    if (!std::isnan(c.late)) spec.values[480000] = c.late;
    const auto bytes = test::nifti_bytes(spec);
    const NiftiImage whole = decode_nifti(bytes);
    for (const bool gzip : {true, false}) {
      const fs::path file = dir / (gzip ? "v.nii.gz" : "v.nii");
      test::write_bytes(file, bytes, gzip);
      const NiftiImage read = read_nifti(file);
      SCOPED_TRACE(testing::Message() << "type " << type << " inter " << c.inter << " late "
                                      << c.late << (gzip ? " gzip" : " raw"));
      ASSERT_EQ(read.volume.holds_int16(), whole.volume.holds_int16());
      ASSERT_EQ(read.volume.sample_bytes(), whole.volume.sample_bytes());
      const bool same = read.volume.visit([&](const auto* a) {
        return whole.volume.visit([&](const auto* b) {
          return std::memcmp(a, b, read.volume.sample_bytes()) == 0;
        });
      });
      EXPECT_TRUE(same);
      EXPECT_EQ(read.values.min, whole.values.min);
      EXPECT_EQ(read.values.max, whole.values.max);
      EXPECT_EQ(read.values.non_finite, whole.values.non_finite);
      EXPECT_EQ(read.values.all_integer, whole.values.all_integer);
      EXPECT_EQ(read.warnings, whole.warnings);
      // Cut short (inside a sample): the reason decode_nifti gives.
      auto cut = bytes;
      cut.resize(bytes.size() - 5);
      test::write_bytes(file, cut, gzip);
      std::string reason, expected;
      try {
        read_nifti(file);
      } catch (const ReadError& error) {
        reason = error.what();
      }
      try {
        decode_nifti(cut);
      } catch (const ReadError& error) {
        expected = error.what();
      }
      EXPECT_FALSE(expected.empty());
      EXPECT_EQ(reason, expected);
    }
  }
  fs::remove_all(dir);
}

// gzip members one after another (as gzip allows; pigz and concatenated files write them),
// then bytes that are no member: read as the members' bytes, the rest ignored.
TEST(NiftiReader, GzipMembersInSequence) {
  const fs::path dir = test::fresh_dir("nifti_members");
  NiftiSpec spec = small_spec(test::kDtInt16);
  spec.dim = {3, 64, 64, 9, 1, 1, 1, 1};
  spec.values.clear();
  for (int v = 0; v < 64 * 64 * 9; ++v) spec.values.push_back(v % 3001 - 1000);
  const auto raw = test::nifti_bytes(spec);
  for (const std::size_t cut : {std::size_t{1}, std::size_t{350}, raw.size() / 2, raw.size() - 1}) {
    const test::FileBytes first(raw.begin(), raw.begin() + static_cast<std::ptrdiff_t>(cut));
    const test::FileBytes second(raw.begin() + static_cast<std::ptrdiff_t>(cut), raw.end());
    test::FileBytes gz = test::gzip_bytes(first);
    const test::FileBytes more = test::gzip_bytes(second);
    gz.insert(gz.end(), more.begin(), more.end());
    gz.push_back(0);  // trailing garbage
    test::write_bytes(dir / "m.nii.gz", gz, false);
    const NiftiImage image = read_nifti(dir / "m.nii.gz");
    ASSERT_TRUE(image.volume.holds_int16()) << cut;
    const NiftiImage whole = decode_nifti(raw);
    EXPECT_TRUE(image.volume.int16_samples() == whole.volume.int16_samples()) << cut;
  }
  fs::remove_all(dir);
}

TEST(NiftiReader, MemoryBoundCheckedFromTheHeader) {
  ReadOptions options;
  options.max_volume_bytes = 64;
  EXPECT_THROW(decode_nifti(test::nifti_bytes(small_spec()), options), ReadError);
}

TEST(NiftiRealData, SharedNiftiFilesLoad) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  for (const char* name : {"bet.nii.gz", "pve_1.nii.gz"}) {
    const fs::path path = data / "nifti" / name;
    if (!fs::exists(path)) GTEST_SKIP() << path << " absent";
    const NiftiImage image = read_nifti(path);
    EXPECT_GT(image.volume.size().voxels(), 1000) << name;
    EXPECT_GT(image.volume.geometry().spacing(0), 0.1) << name;
    EXPECT_LT(image.volume.geometry().spacing(0), 10) << name;
    EXPECT_LT(image.values.min, image.values.max) << name;
    EXPECT_EQ(image.values.non_finite, 0u) << name;
  }
}

}  // namespace
}  // namespace typemerge::nifti
