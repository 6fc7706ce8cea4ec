// AtomicFile: write to a temporary file beside the target, fsync, then rename over it.
//
// An interrupted run leaves either the previous file or none under the final name, never a
// truncated one. The temporary name is '.' + the target's name + six characters + '.partial';
// it is removed on every error path we control. A killed process cannot remove its own, so
// the writer holds an exclusive flock(2) on it while it writes (released by the kernel when
// the process dies), and every new AtomicFile for the same target removes the temporary files
// of that name no process holds: a killed run's left-over goes with the next write of its
// target. Where the file system has no locks, nothing is removed.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace typemerge::io {

class AtomicFile {
 public:
  // Throws std::runtime_error when the temporary file cannot be created.
  explicit AtomicFile(const std::filesystem::path& target);
  ~AtomicFile();  // discards the temporary file unless commit() succeeded
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(const void* data, std::size_t bytes);  // throws on a short write
  void write(std::string_view text) { write(text.data(), text.size()); }
  void commit();  // flush, fsync, rename; throws on failure

 private:
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

}  // namespace typemerge::io
