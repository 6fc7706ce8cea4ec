// The loader's choice of sample storage: int16 for integer rescale with every value in range,
// float otherwise (a fractional slope, a value beyond int16, resampled slices), and the same
// values whichever it chose.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "ct_writer/ct_writer.h"
#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "support/scratch_files.h"

namespace typemerge::dicom {
namespace {

namespace fs = std::filesystem;
using ct_writer::SeriesLayout;

SeriesLayout layout(const std::string& seed) {
  SeriesLayout l;
  l.uid_seed = seed;
  l.columns = 12;
  l.rows = 10;
  l.slices = 5;
  l.pixel_spacing = {0.8, 0.7};
  l.slice_spacing = 2.0;
  l.hu = [](int i, int j, int k) { return (i > 3 && j > 2 && k > 0) ? 700.0 + i : -1000.0 + j; };
  return l;
}

// Writes the series, loads it with int16 allowed and with float only.
struct Loaded {
  LoadedSeries allowed;
  LoadedSeries float_only;
};

Loaded write_and_load(const SeriesLayout& l, const std::string& name,
                      const std::function<void(ct_writer::CtSliceSpec&)>& edit = {}) {
  const fs::path dir = test::fresh_dir(name, "typemerge_int16_");
  auto specs = ct_writer::make_axial_series(l);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    if (edit) edit(specs[k]);
    ct_writer::write_ct_slice(specs[k], dir / ("slice" + std::to_string(k) + ".dcm"));
  }
  const FolderScan scan = scan_folder(dir, ScanOptions{});
  EXPECT_TRUE(scan.default_series.has_value());
  const SeriesInfo& series = scan.series.at(*scan.default_series);
  Loaded loaded{load_series(series), {}};
  LoadOptions float_only;
  float_only.int16_samples = false;
  loaded.float_only = load_series(series, float_only);
  fs::remove_all(dir);
  return loaded;
}

void expect_same_values(const core::Volume& a, const core::Volume& b) {
  ASSERT_EQ(a.size(), b.size());
  const auto& n = a.size();
  for (std::int64_t k = 0; k < n.nz; ++k) {
    for (std::int64_t j = 0; j < n.ny; ++j) {
      for (std::int64_t i = 0; i < n.nx; ++i) {
        ASSERT_EQ(a.at(i, j, k), b.at(i, j, k)) << i << "," << j << "," << k;
      }
    }
  }
}

TEST(Int16Loading, IntegerRescaleGivesInt16Samples) {
  const Loaded loaded = write_and_load(layout("int16_integer"), "integer");
  EXPECT_TRUE(loaded.allowed.volume.holds_int16());
  EXPECT_FALSE(loaded.float_only.volume.holds_int16());
  expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
  EXPECT_EQ(loaded.allowed.min_hu, loaded.float_only.min_hu);
  EXPECT_EQ(loaded.allowed.max_hu, loaded.float_only.max_hu);
  EXPECT_EQ(loaded.allowed.volume.at(5, 4, 2), 705.0f);
}

TEST(Int16Loading, FractionalSlopeGivesFloatSamples) {
  SeriesLayout l = layout("int16_fractional");
  l.rescale_slope = 0.5;
  l.rescale_intercept = -1000;
  l.stored_value = [](int i, int, int) { return 2 * i + 1; };  // odd: HU with a half
  const Loaded loaded = write_and_load(l, "fractional");
  EXPECT_FALSE(loaded.allowed.volume.holds_int16());
  expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
  EXPECT_EQ(loaded.allowed.volume.at(1, 0, 0), -998.5f);
}

TEST(Int16Loading, ValueBeyondInt16FallsBackToFloat) {
  SeriesLayout l = layout("int16_beyond");
  l.bits_stored = 16;
  l.high_bit = 15;
  l.rescale_intercept = -1024;
  // 65000 − 1024 = 63976 HU does not fit int16; every other value does.
  l.stored_value = [](int i, int j, int k) { return i == 2 && j == 3 && k == 4 ? 65000 : 1000; };
  const Loaded loaded = write_and_load(l, "beyond");
  EXPECT_FALSE(loaded.allowed.volume.holds_int16());
  expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
  EXPECT_EQ(loaded.allowed.volume.at(2, 3, 4), 63976.0f);
  EXPECT_EQ(loaded.allowed.max_hu, 63976.0f);
}

// Signed stored values, an integer slope other than 1 and a padding range: the int16 samples
// (decoded in integers) equal the float route's values, padding included.
TEST(Int16Loading, SignedIntegerSlopeAndPaddingGiveTheFloatRoutesValues) {
  SeriesLayout l = layout("int16_signed_slope");
  l.pixel_representation = 1;
  l.bits_stored = 16;
  l.high_bit = 15;
  l.rescale_slope = 2;
  l.rescale_intercept = -100;
  l.stored_value = [](int i, int j, int k) {
    return i == 0 && j == 0 ? -3000 : 40 * i - 30 * j + k;
  };
  const Loaded loaded = write_and_load(l, "signed_slope", [](ct_writer::CtSliceSpec& spec) {
    spec.pixel_padding_value = -3000;
  });
  EXPECT_TRUE(loaded.allowed.volume.holds_int16());
  expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
  EXPECT_EQ(loaded.allowed.volume.at(0, 0, 1), -1000.0f);  // padding: air
  EXPECT_EQ(loaded.allowed.volume.at(3, 9, 2), -396.0f);   // 2 · (120 − 270 + 2) − 100
  EXPECT_EQ(loaded.allowed.min_hu, loaded.float_only.min_hu);
  EXPECT_EQ(loaded.allowed.max_hu, loaded.float_only.max_hu);
}

// Slope 1 (decoded eight words at a time where SSE2 is there): stored widths and high bits with
// bits above the stored ones, signed and unsigned, padding, and values at int16's ends, on
// frames of 91 pixels (not a multiple of eight): the int16 samples equal the float route's.
TEST(Int16Loading, SlopeOneLayoutsGiveTheFloatRoutesValues) {
  struct Case {
    const char* name;
    std::uint16_t bits_stored, high_bit, representation;
    double intercept;
    std::function<std::int32_t(int, int, int)> stored;  // the whole 16-bit word
    std::optional<std::int32_t> padding;
  };
  const Case cases[] = {
      {"unsigned12", 12, 11, 0, -1024,
       [](int i, int j, int k) { return (0xA000 | (37 * i + 301 * j + 7 * k)) & 0xFFFF; },
       std::nullopt},
      {"signed12_high13", 12, 13, 1, -1000,
       [](int i, int j, int k) { return ((((i * 97 - j * 211 + k) & 0xFFF) << 2) | 0x3) & 0xFFFF; },
       std::nullopt},
      {"signed16_padding", 16, 15, 1, -24,
       [](int i, int j, int k) {
         return i == j ? 0xF830 : ((i * 4099 + j * 271 + k) % 60001 - 30000) & 0xFFFF;
       },
       std::int32_t{-2000}},
      {"unsigned16_to_int16_max", 16, 15, 0, -1024,
       [](int i, int j, int k) { return i == 12 ? 33791 : 1024 + 3 * i - 5 * j + k; },
       std::nullopt},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    SeriesLayout l = layout(std::string("int16_slope1_") + c.name);
    l.columns = 13;
    l.rows = 7;
    l.bits_stored = c.bits_stored;
    l.high_bit = c.high_bit;
    l.pixel_representation = c.representation;
    l.rescale_intercept = c.intercept;
    l.stored_value = c.stored;
    const Loaded loaded = write_and_load(l, c.name, [&](ct_writer::CtSliceSpec& spec) {
      spec.pixel_padding_value = c.padding;
    });
    EXPECT_TRUE(loaded.allowed.volume.holds_int16());
    expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
    // The range the decoder reports is the samples' own.
    float lowest = INFINITY, highest = -INFINITY;
    loaded.allowed.volume.visit([&](const auto* samples) {
      for (std::int64_t v = 0; v < loaded.allowed.volume.size().voxels(); ++v) {
        lowest = std::min(lowest, static_cast<float>(samples[v]));
        highest = std::max(highest, static_cast<float>(samples[v]));
      }
    });
    EXPECT_EQ(loaded.allowed.min_hu, lowest);
    EXPECT_EQ(loaded.allowed.max_hu, highest);
    EXPECT_EQ(loaded.float_only.min_hu, lowest);
    EXPECT_EQ(loaded.float_only.max_hu, highest);
  }
}

// Below int16 after an integer rescale: float samples, the same values.
TEST(Int16Loading, ValueBelowInt16FallsBackToFloat) {
  SeriesLayout l = layout("int16_below");
  l.pixel_representation = 1;
  l.bits_stored = 16;
  l.high_bit = 15;
  l.rescale_slope = 3;
  l.rescale_intercept = -1024;
  l.stored_value = [](int i, int j, int k) { return i == 1 && j == 2 && k == 3 ? -20000 : 100; };
  const Loaded loaded = write_and_load(l, "below");
  EXPECT_FALSE(loaded.allowed.volume.holds_int16());
  expect_same_values(loaded.allowed.volume, loaded.float_only.volume);
  EXPECT_EQ(loaded.allowed.volume.at(1, 2, 3), -61024.0f);
}

}  // namespace
}  // namespace typemerge::dicom
