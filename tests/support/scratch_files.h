// Scratch folders and whole-file reads for the tests that write files.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

namespace typemerge::test {

inline std::string read_file_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The folders fresh_dir made in this process, removed when it exits, unless a test failed
// (their files are then what to look at). Kept, a run of the suites left about 700 MB in 230
// folders in the temporary folder. Children forked by a test leave by _exit and remove nothing.
class ScratchFolders {
 public:
  void add(const std::filesystem::path& dir) {
    const std::lock_guard lock(mutex_);
    dirs_.push_back(dir);
  }
  ~ScratchFolders() {
    if (::getpid() != owner_ || ::testing::UnitTest::GetInstance()->Failed()) return;
    for (const std::filesystem::path& dir : dirs_) {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  }

 private:
  pid_t owner_ = ::getpid();
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

inline ScratchFolders& scratch_folders() {
  static ScratchFolders folders;
  return folders;
}

// A new empty folder under the temporary folder, private to this process (ctest runs the
// tests of one executable in parallel processes), removed when the process ends if no test
// failed. `prefix` names the kind of folder.
inline std::filesystem::path fresh_dir(const std::string& name,
                                       const std::string& prefix = "typemerge_test_") {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    (prefix + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  scratch_folders().add(dir);
  return dir;
}

}  // namespace typemerge::test
