#include "io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace typemerge::io {
namespace {

std::runtime_error io_error(const std::string& what, const std::filesystem::path& path) {
  return std::runtime_error(what + " " + path.string() + ": " + std::strerror(errno));
}

}  // namespace

AtomicFile::AtomicFile(const std::filesystem::path& target) : target_(target) {
  const std::filesystem::path folder = target.has_parent_path() ? target.parent_path() : ".";
  // Built by appending: GCC 12 at -O3 reports a false -Wrestrict on "." + std::string.
  std::string name = ".";
  name += target.filename().string();
  name += ".XXXXXX.partial";
  std::string pattern = (folder / name).string();
  const int descriptor = mkstemps(pattern.data(), static_cast<int>(std::strlen(".partial")));
  if (descriptor < 0) throw io_error("cannot create a temporary file for", target);
  temporary_ = pattern;
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
  const int closed = std::fclose(file_);
  file_ = nullptr;
  if (closed != 0) throw io_error("cannot close", temporary_);
  ::chmod(temporary_.c_str(), 0644);  // mkstemp makes 0600; outputs are ordinary files
  if (std::rename(temporary_.c_str(), target_.c_str()) != 0) throw io_error("cannot rename to", target_);
  committed_ = true;
}

}  // namespace typemerge::io
