// Writes ZIP archives with libzip for the tests: files under chosen entry names, zero-filled
// entries, symbolic-link entries.
#pragma once

#include <sys/stat.h>
#include <zip.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace typemerge::test {

struct ZipEntry {
  std::string name;
  std::string bytes;
  bool symlink = false;
  bool store = false;  // no compression
};

inline void write_zip(const std::filesystem::path& file, const std::vector<ZipEntry>& entries) {
  int code = 0;
  zip_t* archive = zip_open(file.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
  if (archive == nullptr) throw std::runtime_error("zip_open failed");
  for (const ZipEntry& entry : entries) {
    zip_source_t* source = zip_source_buffer(archive, entry.bytes.data(), entry.bytes.size(), 0);
    const zip_int64_t index = zip_file_add(archive, entry.name.c_str(), source, ZIP_FL_OVERWRITE);
    if (index < 0) throw std::runtime_error("zip_file_add failed");
    if (entry.store) zip_set_file_compression(archive, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
    if (entry.symlink) {
      zip_file_set_external_attributes(archive, static_cast<zip_uint64_t>(index), 0,
                                       ZIP_OPSYS_UNIX, (S_IFLNK | 0777u) << 16);
    }
  }
  if (zip_close(archive) != 0) throw std::runtime_error("zip_close failed");
}

// Every regular file under `folder`, named by its path relative to it.
inline std::vector<ZipEntry> folder_entries(const std::filesystem::path& folder,
                                            const std::string& prefix);

}  // namespace typemerge::test

#include "support/scratch_files.h"

namespace typemerge::test {

inline std::vector<ZipEntry> folder_entries(const std::filesystem::path& folder,
                                            const std::string& prefix) {
  std::vector<ZipEntry> entries;
  for (const auto& item : std::filesystem::recursive_directory_iterator(folder)) {
    if (!item.is_regular_file()) continue;
    entries.push_back({prefix + std::filesystem::relative(item.path(), folder).string(),
                       read_file_bytes(item.path())});
  }
  return entries;
}

}  // namespace typemerge::test
