// The loader against an independent reference, dcm2niix, on every real series in the shared
// data: same dimensions, same spacing, same voxel values (up to dcm2niix's axis flips).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "dicom/pixel_reader.h"
#include "dicom/series_loader.h"
#include "support/nifti_reader.h"
#include "support/scratch_files.h"
#include "support/test_data.h"

namespace typemerge::dicom {
namespace {

namespace fs = std::filesystem;

fs::path run_dcm2niix(const fs::path& input, const std::string& name) {
  const fs::path out = test::fresh_dir(name, "typemerge_dcm2niix_");
  const std::string command = "dcm2niix -z n -b n -f %s_%j -o '" + out.string() + "' '" +
                              input.string() + "' > '" + (out / "log.txt").string() + "' 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0) << "dcm2niix failed or is not installed: " << command;
  return out;
}

// The dcm2niix output whose size matches: tilt-corrected or equalised variants have other
// sizes, so the raw stack is the one with the same dimensions.
test::NiftiImage matching_nifti(const fs::path& folder, const core::VolumeSize& size) {
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.path().extension() != ".nii") continue;
    test::NiftiImage image;
    try {
      image = test::read_nifti(entry.path());
    } catch (const std::runtime_error&) {
      continue;  // colour secondary captures and the like
    }
    if (image.dims == std::array<std::int64_t, 3>{size.nx, size.ny, size.nz}) return image;
  }
  ADD_FAILURE() << "no dcm2niix output of size " << size.nx << "x" << size.ny << "x" << size.nz;
  return {};
}

// dcm2niix may flip rows and the slice order; find the flips under which every voxel agrees.
// `padding_hu` is the HU of PixelPaddingValue, which dcm2niix keeps and the loader maps to air.
bool same_values_up_to_flips(const core::Volume& ours, const test::NiftiImage& theirs,
                             std::optional<double> padding_hu) {
  const auto& n = ours.size();
  for (int flips = 0; flips < 8; ++flips) {
    bool all = true;
    for (std::int64_t k = 0; k < n.nz && all; ++k) {
      const std::int64_t tk = (flips & 4) ? n.nz - 1 - k : k;
      for (std::int64_t j = 0; j < n.ny && all; ++j) {
        const std::int64_t tj = (flips & 2) ? n.ny - 1 - j : j;
        for (std::int64_t i = 0; i < n.nx; ++i) {
          const std::int64_t ti = (flips & 1) ? n.nx - 1 - i : i;
          double expected = theirs.at(ti, tj, tk);
          if (padding_hu && expected == *padding_hu) expected = kAirHu;
          if (std::abs(ours.at(i, j, k) - expected) > 1e-3) {
            all = false;
            break;
          }
        }
      }
    }
    if (all) return true;
  }
  return false;
}

struct Case {
  const char* folder;
  std::int64_t nx, ny, nz;
  double sx, sy, sz;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.folder; }

class RealSeries : public ::testing::TestWithParam<Case> {};

TEST_P(RealSeries, MatchesDcm2niix) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const Case& c = GetParam();
  const fs::path input = data / "ct" / c.folder;
  const FolderScan scan = scan_folder(input, {});
  ASSERT_TRUE(scan.default_series.has_value()) << "no default series in " << input;
  const SeriesInfo& series = scan.series[*scan.default_series];
  const LoadedSeries loaded = load_series(series);
  const auto& size = loaded.volume.size();
  EXPECT_EQ(size, (core::VolumeSize{c.nx, c.ny, c.nz}));
  EXPECT_NEAR(loaded.volume.geometry().spacing(0), c.sx, 1e-3);
  EXPECT_NEAR(loaded.volume.geometry().spacing(1), c.sy, 1e-3);
  EXPECT_NEAR(series.geometry.slice_step_mm, c.sz, 1e-3);

  const test::NiftiImage reference = matching_nifti(run_dcm2niix(input, c.folder), size);
  ASSERT_FALSE(reference.values.empty());
  EXPECT_NEAR(reference.pixdim[0], c.sx, 1e-3);
  EXPECT_NEAR(reference.pixdim[1], c.sy, 1e-3);
  EXPECT_NEAR(reference.pixdim[2], c.sz, 1e-3);
  EXPECT_TRUE(same_values_up_to_flips(loaded.volume, reference, std::nullopt));
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealSeries,
    ::testing::Values(Case{"abdomen", 512, 512, 134, 1.0742, 1.0742, 3.0},
                      Case{"head64_resampled", 64, 64, 93, 3.2, 3.2, 1.5},
                      Case{"phantom_study", 512, 512, 28, 0.4512, 0.4512, 5.0}),
    [](const auto& info) { return std::string(info.param.folder); });

TEST(RealSeries, PhantomStudyPicksTheCtAndSaysWhatItSkipped) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const FolderScan scan = scan_folder(data / "ct" / "phantom_study", {});
  ASSERT_TRUE(scan.default_series.has_value());
  EXPECT_EQ(scan.series[*scan.default_series].slices.size(), 28u);
  int localizers = 0;
  for (const auto& series : scan.series) localizers += series.role == SeriesRole::localizer;
  EXPECT_EQ(localizers, 1);  // S1000, the scout
  int secondary_captures = 0, directories = 0;
  for (const auto& file : scan.skipped) {
    secondary_captures += file.reason.find("secondary capture") != std::string::npos;
    directories += file.reason.find("DICOMDIR") != std::string::npos;
  }
  EXPECT_GE(secondary_captures, 1);  // S4010
  EXPECT_GE(directories, 1);         // DIRFILE
}

TEST(RealSeries, HeadWithoutHounsfieldUnitsIsFlagged) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const FolderScan scan = scan_folder(data / "ct" / "head64_resampled", {});
  ASSERT_TRUE(scan.default_series.has_value());
  const LoadedSeries loaded = load_series(scan.series[*scan.default_series]);
  bool flagged = false;
  for (const auto& w : loaded.warnings) flagged |= w.find("Hounsfield") != std::string::npos;
  EXPECT_TRUE(flagged);
}

TEST(RealSeries, TiltedVariableSpacingIsRefusedThenResampledOnRequest) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path input = data / "ct" / "head_tilt_variable";
  const FolderScan strict = scan_folder(input, {});
  ASSERT_EQ(strict.series.size(), 1u);
  EXPECT_FALSE(strict.default_series.has_value());
  EXPECT_NE(strict.series[0].geometry.error.find("not uniform"), std::string::npos);

  ScanOptions options;
  options.geometry.spacing = SpacingPolicy::resample;
  const FolderScan scan = scan_folder(input, options);
  ASSERT_TRUE(scan.default_series.has_value());
  const SeriesInfo& series = scan.series[*scan.default_series];
  EXPECT_NEAR(series.geometry.tilt_degrees, 18.5, 0.01);  // GantryDetectorTilt says +18.5
  const LoadedSeries resampled = load_series(series);
  // The grid's slice axis follows the table (a shear), and the first and last slices are the
  // acquired ones.
  const auto& map = resampled.volume.geometry();
  const auto last = map.apply(0, 0, static_cast<double>(resampled.volume.size().nz - 1));
  EXPECT_NEAR(last[2], (*series.slices.back().position)[2], 1.2);

  // The acquired slices, stacked without resampling, equal dcm2niix's raw stack voxel for voxel
  // (dcm2niix keeps PixelPaddingValue −1500; the loader maps it to air).
  SeriesInfo acquired = series;
  acquired.geometry.needs_resampling = false;
  acquired.geometry.output_slices = static_cast<std::int64_t>(series.slices.size());
  const LoadedSeries stacked = load_series(acquired);
  const test::NiftiImage reference =
      matching_nifti(run_dcm2niix(input, "head_tilt_variable"), stacked.volume.size());
  ASSERT_FALSE(reference.values.empty());
  EXPECT_TRUE(same_values_up_to_flips(stacked.volume, reference, -1500.0));
}

}  // namespace
}  // namespace typemerge::dicom
