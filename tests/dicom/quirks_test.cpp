// Every file of the shared quirks collection either decodes to the same pixels as its
// uncompressed twin (lossless), close to them (lossy, with its own rescale), or is refused
// with a reason that names the file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "dicom/header_reader.h"
#include "dicom/pixel_reader.h"
#include "support/test_data.h"

namespace typemerge::dicom {
namespace {

namespace fs = std::filesystem;

struct DecodedFile {
  std::vector<SliceHeader> frames;
  std::vector<std::vector<float>> hu;
  std::string error;
};

DecodedFile decode(const fs::path& file) {
  DecodedFile decoded;
  HeaderReadResult read = read_headers(file, {});
  if (!read.skip_reason.empty()) {
    decoded.error = read.skip_reason;
    return decoded;
  }
  decoded.frames = read.frames;
  std::vector<FrameTarget> targets;
  decoded.hu.resize(decoded.frames.size());
  for (std::size_t f = 0; f < decoded.frames.size(); ++f) {
    decoded.hu[f].resize(std::size_t{decoded.frames[f].rows} * decoded.frames[f].columns);
    targets.push_back({&decoded.frames[f], decoded.hu[f].data()});
  }
  try {
    read_frames_hu(targets);
  } catch (const PixelError& error) {
    decoded.error = error.what();
  }
  return decoded;
}

double mean_difference(const DecodedFile& a, const DecodedFile& b, bool absolute,
                       double offset = 0) {
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t f = 0; f < a.hu.size(); ++f) {
    for (std::size_t p = 0; p < a.hu[f].size(); ++p) {
      const double d = a.hu[f][p] - b.hu[f][p] - offset;
      sum += absolute ? std::abs(d) : d;
    }
    count += a.hu[f].size();
  }
  return sum / static_cast<double>(count);
}

double mean_abs_difference(const DecodedFile& a, const DecodedFile& b) {
  return mean_difference(a, b, true);
}

bool is_lossy(const std::string& name) {
  // .50 baseline, .51 extended, .53 spectral selection, .55 full progression: all DCT, lossy.
  for (const char* marker : {"JPEGProcess1Transfer", "JPEGProcess2_4", "JPEGProcess6_8",
                             "JPEGProcess10_12", "JPEGLSLossy",
                             "JPEG2000TransferSyntax", "jpeg_baseline", "jpeg_ls.81"}) {
    if (name.find(marker) != std::string::npos) return true;
  }
  return false;
}

// Compares every file of `folder` with `reference` (decoded the same way).
void expect_twins(const fs::path& folder, const fs::path& reference_file,
                  const std::vector<std::string>& skip_names = {}) {
  const DecodedFile reference = decode(reference_file);
  ASSERT_TRUE(reference.error.empty()) << reference.error;
  int compared = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file() || name == "LICENSE" || entry.path() == reference_file) continue;
    if (std::find(skip_names.begin(), skip_names.end(), name) != skip_names.end()) continue;
    SCOPED_TRACE(name);
    const DecodedFile decoded = decode(entry.path());
    ASSERT_TRUE(decoded.error.empty()) << decoded.error;
    ASSERT_EQ(decoded.frames.size(), reference.frames.size());
    ASSERT_EQ(decoded.hu.front().size(), reference.hu.front().size());
    if (is_lossy(name)) {
      // A lossy file is within a few quantisation steps of its twin on average; an 8-bit
      // re-encoding of 16-bit data has a step of its RescaleSlope (32 HU for the .50 file).
      const double step = std::max(1.0, decoded.frames.front().rescale_slope);
      double offset = 0;
      if (name == "CT0012.fragmented_no_bot_jpeg_baseline.51.dcm") {
        // This file's stored values sit 1023 above its twin's under the same rescale: DCMTK's
        // dcmdjpeg decodes it so too, so the offset is in the file, not in the decoder.
        offset = mean_difference(decoded, reference, false);
        EXPECT_NEAR(offset, 1023.0, 2.0);
      }
      EXPECT_LT(mean_difference(decoded, reference, true, offset), 4.0 + step)
          << "lossy file far from its twin";
    } else {
      EXPECT_EQ(mean_abs_difference(decoded, reference), 0.0) << "lossless file differs";
    }
    ++compared;
  }
  EXPECT_GT(compared, 0);
}

TEST(Quirks, TransferSyntaxesDecodeToTheSamePixels) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path folder = data / "quirks" / "transfer_syntaxes";
  expect_twins(folder, folder / "CTImage.dcm", {"CT1_J2KR", "CT2_J2KR"});
}

TEST(Quirks, NemaJpeg2000MatchesItsUncompressedTwin) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const DecodedFile j2k = decode(data / "quirks" / "transfer_syntaxes" / "CT1_J2KR");
  const DecodedFile raw =
      decode(data / "quirks" / "encapsulated_multiframe" / "CT1_UNC.explicit_little_endian.dcm");
  ASSERT_TRUE(j2k.error.empty()) << j2k.error;
  ASSERT_TRUE(raw.error.empty()) << raw.error;
  ASSERT_EQ(j2k.hu.front().size(), raw.hu.front().size());
  EXPECT_EQ(mean_abs_difference(j2k, raw), 0.0);
  const DecodedFile second = decode(data / "quirks" / "transfer_syntaxes" / "CT2_J2KR");
  EXPECT_TRUE(second.error.empty()) << second.error;
}

TEST(Quirks, EncapsulatedSingleFrames) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path folder = data / "quirks" / "encapsulated_multiframe" / "encapsulated" / "single-frame";
  expect_twins(folder, folder / "CT1_UNC.explicit_little_endian.dcm");
}

TEST(Quirks, EncapsulatedMultiFrameEnhancedCt) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path folder = data / "quirks" / "encapsulated_multiframe" / "encapsulated" / "multi-frame";
  expect_twins(folder, folder / "CT0012.explicit_little_endian.dcm");
  // The geometry exists only in the functional groups: each frame must have found it.
  const DecodedFile reference = decode(folder / "CT0012.explicit_little_endian.dcm");
  ASSERT_EQ(reference.frames.size(), 2u);
  for (const auto& frame : reference.frames) {
    EXPECT_TRUE(frame.position.has_value());
    EXPECT_TRUE(frame.pixel_spacing.has_value());
    EXPECT_TRUE(frame.has_rescale);
  }
}

TEST(Quirks, ByteOrderTwinsOfTheNemaSlice) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path folder = data / "quirks" / "encapsulated_multiframe";
  const DecodedFile little = decode(folder / "CT1_UNC.explicit_little_endian.dcm");
  for (const char* twin : {"CT1_UNC.explicit_big_endian.dcm", "CT1_UNC.implicit_little_endian.dcm"}) {
    const DecodedFile other = decode(folder / twin);
    ASSERT_TRUE(other.error.empty()) << twin << ": " << other.error;
    EXPECT_EQ(mean_abs_difference(other, little), 0.0) << twin;
  }
}

TEST(Quirks, PydicomCts) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path folder = data / "quirks" / "pydicom_ct";
  const DecodedFile raw = decode(folder / "693_UNCR.dcm");
  const DecodedFile j2k = decode(folder / "693_J2KR.dcm");
  ASSERT_TRUE(raw.error.empty()) << raw.error;
  ASSERT_TRUE(j2k.error.empty()) << j2k.error;
  EXPECT_EQ(mean_abs_difference(raw, j2k), 0.0);
  // Signed 14-bit stored values: sign extension from bit 13 must give negative HU for air.
  const DecodedFile signed14 = decode(folder / "693_UNCI.dcm");
  ASSERT_TRUE(signed14.error.empty()) << signed14.error;
  EXPECT_EQ(signed14.frames.front().bits_stored, 14);
  EXPECT_EQ(signed14.frames.front().pixel_representation, 1);
  const auto [lo, hi] = std::minmax_element(signed14.hu.front().begin(), signed14.hu.front().end());
  EXPECT_LT(*lo, -500.0f);
  EXPECT_GT(*hi, 0.0f);
  const DecodedFile enhanced = decode(folder / "eCT_Supplemental.dcm");
  EXPECT_TRUE(enhanced.error.empty()) << enhanced.error;
}

}  // namespace
}  // namespace typemerge::dicom
