// extract_zip: limits against zip bombs, entry names that try to leave the folder, damaged
// archives, and the private folder's life.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>

#include "support/scratch_files.h"
#include "zip_input/zip_extract.h"
#include "zip_maker.h"

namespace typemerge::zip_input {
namespace {

namespace fs = std::filesystem;

// Each test gets its own TMPDIR, so leftovers of the private folders can be counted.
class ZipExtract : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::fresh_dir(std::string("zip_") +
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    tmp_ = dir_ / "tmp";
    fs::create_directories(tmp_);
    const char* old = std::getenv("TMPDIR");
    if (old != nullptr) old_tmpdir_ = old;
    had_tmpdir_ = old != nullptr;
    ::setenv("TMPDIR", tmp_.c_str(), 1);
  }
  void TearDown() override {
    if (had_tmpdir_) {
      ::setenv("TMPDIR", old_tmpdir_.c_str(), 1);
    } else {
      ::unsetenv("TMPDIR");
    }
    fs::remove_all(dir_);
  }
  std::size_t leftovers() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(tmp_), fs::directory_iterator()));
  }
  static void expect_refused(const fs::path& archive, const std::string& expected,
                             const ZipLimits& limits = {}) {
    try {
      extract_zip(archive, limits);
      ADD_FAILURE() << "accepted; expected: " << expected;
    } catch (const ZipError& error) {
      EXPECT_NE(std::string(error.what()).find(expected), std::string::npos) << error.what();
      EXPECT_EQ(std::string(error.what()).find(archive.filename().string()), std::string::npos);
    }
  }

  fs::path dir_, tmp_;
  std::string old_tmpdir_;
  bool had_tmpdir_ = false;
};

TEST_F(ZipExtract, FilesUnderNumberedNamesInAPrivateFolderRemovedAfter) {
  const fs::path archive = dir_ / "study.zip";
  test::write_zip(archive, {{"Patient_Doe/Series 1/IM0001", "first"},
                            {"Patient_Doe/", ""},
                            {"Patient_Doe/Series 1/IM0002", "second"}});
  ASSERT_TRUE(is_zip_file(archive));
  fs::path folder;
  {
    const ExtractedZip extracted = extract_zip(archive);
    folder = extracted.folder();
    EXPECT_EQ(folder.parent_path(), tmp_);
    EXPECT_EQ(extracted.files, 2u);
    EXPECT_EQ(extracted.bytes, 11u);
    struct stat info {};
    ASSERT_EQ(::stat(folder.c_str(), &info), 0);
    EXPECT_EQ(info.st_mode & 0777, 0700u);
    std::vector<fs::path> files;
    for (const auto& item : fs::directory_iterator(folder)) {
      EXPECT_EQ(item.path().filename().string().find("Doe"), std::string::npos);
      EXPECT_TRUE(item.is_regular_file());
      files.push_back(item.path());
    }
    std::sort(files.begin(), files.end());
    ASSERT_EQ(files.size(), 2u);
    EXPECT_EQ(files[0].filename(), "00000001.dcm");
    EXPECT_EQ(test::read_file_bytes(files[0]) + test::read_file_bytes(files[1]), "firstsecond");
  }
  EXPECT_FALSE(fs::exists(folder));
  EXPECT_EQ(leftovers(), 0u);
}

TEST_F(ZipExtract, TraversalNamesAndLinksStayInside) {
  const fs::path archive = dir_ / "evil.zip";
  test::write_zip(archive, {{"../../escaped_up.dcm", "up"},
                            {"/tmp/escaped_absolute.dcm", "abs"},
                            {"a/../../escaped_mixed.dcm", "mixed"},
                            {"..\\..\\escaped_backslash.dcm", "back"},
                            {"link_to_etc", "/etc/passwd", true}});
  const ExtractedZip extracted = extract_zip(archive);
  EXPECT_EQ(extracted.files, 4u);  // the link is skipped
  ASSERT_EQ(extracted.warnings.size(), 1u);
  EXPECT_NE(extracted.warnings[0].find("symbolic link"), std::string::npos);
  for (const auto& item : fs::recursive_directory_iterator(dir_)) {
    EXPECT_EQ(item.path().filename().string().find("escaped"), std::string::npos) << item.path();
  }
  EXPECT_FALSE(fs::exists("/tmp/escaped_absolute.dcm"));
  for (const auto& item : fs::directory_iterator(extracted.folder())) {
    EXPECT_FALSE(item.is_symlink());
  }
}

TEST_F(ZipExtract, ABombIsRefusedBeforeWriting) {
  const fs::path archive = dir_ / "bomb.zip";
  test::write_zip(archive, {{"zeros.dcm", std::string(std::size_t{64} << 20, '\0')}});
  EXPECT_LT(fs::file_size(archive), std::uintmax_t{1} << 20);
  expect_refused(archive, "zip bomb");
  EXPECT_EQ(leftovers(), 0u);
}

TEST_F(ZipExtract, TotalAndEntryLimits) {
  const fs::path archive = dir_ / "many.zip";
  std::vector<test::ZipEntry> entries;
  for (int n = 0; n < 20; ++n) entries.push_back({"f" + std::to_string(n), std::string(1000, 'x')});
  test::write_zip(archive, entries);
  ZipLimits few_entries;
  few_entries.max_entries = 10;
  expect_refused(archive, "20 entries", few_entries);
  ZipLimits few_bytes;
  few_bytes.max_total_bytes = 5000;
  expect_refused(archive, "limit of", few_bytes);
  ZipLimits strict_ratio;
  strict_ratio.ratio_check_bytes = 100;
  strict_ratio.max_compression_ratio = 2;
  expect_refused(archive, "compressed", strict_ratio);
  EXPECT_EQ(leftovers(), 0u);
  EXPECT_EQ(extract_zip(archive).files, 20u);
}

TEST_F(ZipExtract, DamagedArchivesAreRefusedAndLeaveNothing) {
  const fs::path good = dir_ / "good.zip";
  std::string payload;
  for (int n = 0; n < 5000; ++n) payload += std::to_string(n * 7919 % 10007) + ",";
  test::write_zip(good, {{"a.dcm", payload, false, true}, {"b.dcm", payload}});
  const std::string bytes = test::read_file_bytes(good);

  // Truncated at several places.
  for (std::size_t keep : {std::size_t{0}, std::size_t{10}, bytes.size() / 2, bytes.size() - 5}) {
    const fs::path cut = dir_ / ("cut" + std::to_string(keep) + ".zip");
    std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(keep));
    EXPECT_THROW(extract_zip(cut), ZipError) << keep;
  }
  // A flipped byte inside the stored entry's data: its CRC fails.
  std::string flipped = bytes;
  const std::size_t at = flipped.find(payload.substr(100, 20));
  ASSERT_NE(at, std::string::npos);
  flipped[at] = static_cast<char>(flipped[at] ^ 0x55);
  const fs::path crc = dir_ / "crc.zip";
  std::ofstream(crc, std::ios::binary) << flipped;
  expect_refused(crc, "damaged entry");
  // Not a ZIP at all, and missing.
  const fs::path text = dir_ / "text.zip";
  std::ofstream(text) << "PK but not really a zip archive";
  expect_refused(text, "cannot open");
  EXPECT_FALSE(is_zip_file(dir_ / "missing.zip"));
  expect_refused(dir_ / "missing.zip", "cannot open");
  EXPECT_EQ(leftovers(), 0u);
}

}  // namespace
}  // namespace typemerge::zip_input
