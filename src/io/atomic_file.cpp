#include "io/atomic_file.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string_view>

namespace typemerge::io {
namespace {

std::runtime_error io_error(const std::string& what, const std::filesystem::path& path) {
  return std::runtime_error(what + " " + path.string() + ": " + std::strerror(errno));
}

constexpr std::string_view kRandom = ".XXXXXX";  // mkstemps' six characters, after a dot
constexpr std::string_view kSuffix = ".partial";

// Whether `name` is one of target's temporary names: "." + target + "." + 6 characters +
// ".partial".
bool is_temporary_of(std::string_view name, std::string_view target) {
  return name.size() == 1 + target.size() + kRandom.size() + kSuffix.size() &&
         name.front() == '.' &&
         name.substr(1, target.size()) == target && name[1 + target.size()] == '.' &&
         name.substr(name.size() - kSuffix.size()) == kSuffix;
}

// Removes target's temporary files that no process holds locked (left by killed runs),
// except `own`. A file is removed while this process holds its lock, so a writer that locks
// it later finds its name gone and starts again (see the constructor).
void remove_stale_temporaries(const std::filesystem::path& folder, const std::string& target,
                              const std::filesystem::path& own) {
  std::error_code error;
  std::filesystem::directory_iterator entries(folder, error);
  if (error) return;
  for (const auto& entry : entries) {
    const std::string name = entry.path().filename().string();
    if (!is_temporary_of(name, target) || entry.path() == own) continue;
    const int descriptor = ::open(entry.path().c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    if (descriptor < 0) continue;
    struct stat status{};
    if (::fstat(descriptor, &status) == 0 && S_ISREG(status.st_mode) &&
        ::flock(descriptor, LOCK_EX | LOCK_NB) == 0) {
      ::unlink(entry.path().c_str());
    }
    ::close(descriptor);
  }
}

// Whether `path` still names the file open as `descriptor`.
bool still_named(int descriptor, const std::filesystem::path& path) {
  struct stat open_file{};
  struct stat named{};
  return ::fstat(descriptor, &open_file) == 0 && ::stat(path.c_str(), &named) == 0 &&
         open_file.st_dev == named.st_dev && open_file.st_ino == named.st_ino;
}

}  // namespace

AtomicFile::AtomicFile(const std::filesystem::path& target) : target_(target) {
  const std::filesystem::path folder = target.has_parent_path() ? target.parent_path() : ".";
  // Built by appending: GCC 12 at -O3 reports a false -Wrestrict on "." + std::string.
  std::string name = ".";
  name += target.filename().string();
  name += kRandom;
  name += kSuffix;
  int descriptor = -1;
  // Locked at once; a sweeping writer that took the lock first has removed (or is removing)
  // the name: then another name.
  for (int attempt = 0; descriptor < 0; ++attempt) {
    std::string pattern = (folder / name).string();
    descriptor = mkstemps(pattern.data(), static_cast<int>(kSuffix.size()));
    if (descriptor < 0) throw io_error("cannot create a temporary file for", target);
    temporary_ = pattern;
    const bool locked = ::flock(descriptor, LOCK_EX | LOCK_NB) == 0;
    if (!locked && errno != EWOULDBLOCK) break;  // no locks here: nothing is swept either
    if (locked && still_named(descriptor, temporary_)) break;
    ::close(descriptor);
    descriptor = -1;
    if (attempt == 8) throw io_error("cannot hold a temporary file for", target);
  }
  remove_stale_temporaries(folder, target.filename().string(), temporary_);
  file_ = fdopen(descriptor, "wb");
  if (file_ == nullptr) {
    ::close(descriptor);
    std::filesystem::remove(temporary_);
    throw io_error("cannot open", temporary_);
  }
  // Large buffered writes: meshes are written in one pass of many small records.
  std::setvbuf(file_, nullptr, _IOFBF, 1 << 20);
}

AtomicFile::~AtomicFile() {
  if (file_ != nullptr) std::fclose(file_);
  if (!committed_) {
    std::error_code ignored;
    std::filesystem::remove(temporary_, ignored);
  }
}

void AtomicFile::write(const void* data, std::size_t bytes) {
  if (bytes != 0 && std::fwrite(data, 1, bytes, file_) != bytes) {
    throw io_error("cannot write", temporary_);
  }
}

void AtomicFile::commit() {
  if (std::fflush(file_) != 0 || ::fsync(fileno(file_)) != 0) throw io_error("cannot write", target_);
  ::fchmod(fileno(file_), 0644);  // mkstemp makes 0600; outputs are ordinary files
  // Renamed while still open and locked: closed first, the temporary file could be taken for
  // a killed run's and removed by another writer of the same target.
  if (std::rename(temporary_.c_str(), target_.c_str()) != 0) throw io_error("cannot rename to", target_);
  committed_ = true;
  const int closed = std::fclose(file_);
  file_ = nullptr;
  if (closed != 0) throw io_error("cannot close", target_);
}

}  // namespace typemerge::io
