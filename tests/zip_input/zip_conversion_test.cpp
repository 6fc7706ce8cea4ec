// A ZIP of the abdomen loads as its folder does: the same series, the same volume.
#include <gtest/gtest.h>

#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "support/scratch_files.h"
#include "support/test_data.h"
#include "zip_input/zip_extract.h"
#include "zip_maker.h"

namespace typemerge::zip_input {
namespace {

namespace fs = std::filesystem;

// Identifying names, as a PACS export or a person would make them.
constexpr const char* kArchiveName = "Doe_Jane_1970_study.zip";
constexpr const char* kEntryPrefix = "DOE^JANE_PID4242/CT_ABDOMEN/";

class AbdomenZip : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto data = test::real_data_dir();
    if (!data) return;
    folder_ = *data / "ct" / "abdomen";
    dir_ = test::fresh_dir("zip_abdomen");
    archive_ = dir_ / kArchiveName;
    test::write_zip(archive_, test::folder_entries(folder_, kEntryPrefix));
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (folder_.empty()) {
      GTEST_SKIP() << "real CT data not found: set TYPEMERGE_DATA to the shared data folder";
    }
  }

  static fs::path folder_, dir_, archive_;
};
fs::path AbdomenZip::folder_, AbdomenZip::dir_, AbdomenZip::archive_;

TEST_F(AbdomenZip, LoadsTheSameVolumeAsTheFolder) {
  const ExtractedZip extracted = extract_zip(archive_);
  EXPECT_EQ(extracted.files, 136u);
  const dicom::ScanOptions options;
  const dicom::FolderScan from_folder = dicom::scan_folder(folder_, options);
  const dicom::FolderScan from_zip = dicom::scan_folder(extracted.folder(), options);
  ASSERT_TRUE(from_folder.default_series && from_zip.default_series);
  const auto& a = from_folder.series[*from_folder.default_series];
  const auto& b = from_zip.series[*from_zip.default_series];
  EXPECT_EQ(a.id, b.id);
  const dicom::LoadedSeries va = dicom::load_series(a);
  const dicom::LoadedSeries vb = dicom::load_series(b);
  EXPECT_EQ(va.volume.size(), vb.volume.size());
  EXPECT_EQ(va.volume.geometry().origin, vb.volume.geometry().origin);
  ASSERT_EQ(va.volume.sample_type(), vb.volume.sample_type());
  EXPECT_TRUE(va.volume.holds_int16() ? va.volume.int16_samples() == vb.volume.int16_samples()
                                      : va.volume.samples() == vb.volume.samples());
}

}  // namespace
}  // namespace typemerge::zip_input
