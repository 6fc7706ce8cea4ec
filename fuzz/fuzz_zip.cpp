// Fuzz target: one byte string as a ZIP archive through extract_zip, with small limits.
//
// Properties (a violation aborts, so libFuzzer keeps the input):
//  * extract_zip throws nothing but ZipError;
//  * what it extracts stays within the limits: at most max_entries files, at most
//    max_total_bytes bytes, all regular files directly in its private folder;
//  * the private folder is gone once the result is destroyed (or after a refusal): the
//    fuzzer's own temporary folder is empty after every input;
//  * plus everything AddressSanitizer and UndefinedBehaviorSanitizer catch on the way.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "zip_input/zip_extract.h"

namespace {

namespace fs = std::filesystem;

// A private TMPDIR, in memory when /dev/shm exists; the archive is written beside it.
const fs::path& work_folder() {
  static const fs::path path = [] {
    std::error_code error;
    const fs::path base = fs::is_directory("/dev/shm", error) ? fs::path("/dev/shm")
                                                               : fs::temp_directory_path();
    const fs::path folder = base / ("typemerge_fuzz_zip_" + std::to_string(::getpid()));
    fs::create_directories(folder / "tmp");
    return folder;
  }();
  return path;
}

void remove_work_folder() {
  std::error_code error;
  fs::remove_all(work_folder(), error);
}

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_zip: property violated: %s\n", property);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  ::setenv("TMPDIR", (work_folder() / "tmp").c_str(), 1);
  std::atexit(remove_work_folder);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace typemerge::zip_input;
  const fs::path archive = work_folder() / "input.zip";
  {
    std::ofstream out(archive, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  ZipLimits limits;
  limits.max_entries = 64;
  limits.max_total_bytes = std::uint64_t{4} << 20;
  limits.ratio_check_bytes = 4096;
  try {
    const ExtractedZip extracted = extract_zip(archive, limits);
    std::size_t files = 0;
    std::uintmax_t bytes = 0;
    for (const auto& item : fs::directory_iterator(extracted.folder())) {
      if (!item.is_regular_file() || item.is_symlink()) violated("not a regular file");
      ++files;
      bytes += item.file_size();
    }
    if (files != extracted.files || files > limits.max_entries) violated("file count");
    if (bytes != extracted.bytes || bytes > limits.max_total_bytes) violated("byte count");
  } catch (const ZipError&) {
  } catch (...) {
    violated("extract_zip threw something else than ZipError");
  }
  if (fs::directory_iterator(work_folder() / "tmp") != fs::directory_iterator()) {
    violated("a private folder was left behind");
  }
  return 0;
}
