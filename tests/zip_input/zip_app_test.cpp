// A ZIP of the abdomen converts through the executable to the same STL as its folder, byte for
// byte; a zip bomb given to `convert` is refused and leaves no output. Neither the archive's
// name nor its entry names appear in the output, the report or the console.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>

#include "support/scratch_files.h"
#include "support/test_data.h"
#include "zip_maker.h"

namespace typemerge::zip_input {
namespace {

namespace fs = std::filesystem;

struct CommandRun {
  int exit_code = -1;
  std::string out;  // stdout and stderr together
};

CommandRun run(const std::string& arguments) {
  const std::string command = std::string(TYPEMERGE_EXE) + " " + arguments + " 2>&1";
  CommandRun result;
  FILE* pipe = popen(command.c_str(), "r");
  std::array<char, 4096> buffer{};
  while (std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    result.out.append(buffer.data(), n);
  }
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// Identifying names, as a PACS export or a person would make them.
constexpr const char* kArchiveName = "Doe_Jane_1970_study.zip";
constexpr const char* kEntryPrefix = "DOE^JANE_PID4242/CT_ABDOMEN/";

class AbdomenZipConvert : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto data = test::real_data_dir();
    if (!data) return;
    folder_ = *data / "ct" / "abdomen";
    dir_ = test::fresh_dir("zip_abdomen_convert");
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
fs::path AbdomenZipConvert::folder_, AbdomenZipConvert::dir_, AbdomenZipConvert::archive_;

TEST_F(AbdomenZipConvert, ConvertsByteForByteAsTheFolder) {
  if (!test::optimised_build()) {
    // Two abdomen conversions take over 10 minutes under ASan; the ZIP's loading path is
    // checked there by AbdomenZip.LoadsTheSameVolumeAsTheFolder.
    GTEST_SKIP() << "the abdomen's conversions run in the optimised build only";
  }
  const fs::path from_folder = dir_ / "folder.stl";
  const fs::path from_zip = dir_ / "zip.stl";
  const std::string options = " --iso 300 --finish none --keep-table";
  const CommandRun a = run("convert " + folder_.string() + " -o " + from_folder.string() + options);
  ASSERT_EQ(a.exit_code, 0) << a.out;
  const CommandRun b = run("convert " + archive_.string() + " -o " + from_zip.string() + options +
                           " --report " + (dir_ / "report.json").string());
  ASSERT_EQ(b.exit_code, 0) << b.out;
  const std::string stl = test::read_file_bytes(from_zip);
  EXPECT_GT(stl.size(), 1000u);
  EXPECT_TRUE(stl == test::read_file_bytes(from_folder));
  const std::string report = test::read_file_bytes(dir_ / "report.json");
  for (const std::string& text : {b.out, stl.substr(0, 80), report}) {
    for (const char* secret : {"Doe_Jane", "DOE^JANE", "PID4242", "CT_ABDOMEN", "1-001"}) {
      EXPECT_EQ(text.find(secret), std::string::npos) << secret;
    }
  }
}

TEST(ZipConvert, ABombIsRefusedWithoutOutput) {
  const fs::path dir = test::fresh_dir("zip_bomb_convert");
  const fs::path archive = dir / "bomb.zip";
  test::write_zip(archive, {{"zeros.dcm", std::string(std::size_t{64} << 20, '\0')}});
  const fs::path output = dir / "out.stl";
  const CommandRun result =
      run("convert " + archive.string() + " -o " + output.string() + " --iso 300");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.out.find("zip bomb"), std::string::npos) << result.out;
  EXPECT_FALSE(fs::exists(output));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace typemerge::zip_input
