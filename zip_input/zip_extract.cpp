#include "zip_input/zip_extract.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zip.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>

namespace typemerge::zip_input {
namespace {

constexpr std::size_t kChunkBytes = std::size_t{1} << 20;

[[noreturn]] void fail(const std::string& reason) { throw ZipError{"ZIP archive: " + reason}; }

std::string zip_reason(int code) {
  zip_error_t error;
  zip_error_init_with_code(&error, code);
  std::string text = zip_error_strerror(&error);
  zip_error_fini(&error);
  return text;
}

struct ArchiveCloser {
  void operator()(zip_t* archive) const { zip_discard(archive); }
};
struct EntryCloser {
  void operator()(zip_file_t* entry) const { zip_fclose(entry); }
};

class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }

 private:
  int fd_;
};

std::filesystem::path make_private_folder() {
  std::error_code error;
  std::filesystem::path base = std::filesystem::temp_directory_path(error);
  if (error) fail("no temporary folder: " + error.message());
  std::string pattern = (base / "typemerge-zip-XXXXXX").string();
  std::vector<char> buffer(pattern.begin(), pattern.end());
  buffer.push_back('\0');
  if (::mkdtemp(buffer.data()) == nullptr) {
    fail(std::string("cannot make a temporary folder: ") + std::strerror(errno));
  }
  return std::filesystem::path(buffer.data());
}

bool is_symbolic_link(zip_t* archive, zip_uint64_t index) {
  zip_uint8_t system = 0;
  zip_uint32_t attributes = 0;
  if (zip_file_get_external_attributes(archive, index, 0, &system, &attributes) != 0) return false;
  return system == ZIP_OPSYS_UNIX && ((attributes >> 16) & S_IFMT) == S_IFLNK;
}

std::string entry_file_name(std::size_t number) {
  std::array<char, 32> name{};
  std::snprintf(name.data(), name.size(), "%08zu.dcm", number);
  return name.data();
}

// Inflates one entry into `target`, stopping as soon as it exceeds what it declared or what
// the limits leave.
std::uint64_t inflate_entry(zip_t* archive, zip_uint64_t index, std::uint64_t declared,
                            std::uint64_t allowed, const std::filesystem::path& target) {
  std::unique_ptr<zip_file_t, EntryCloser> entry(zip_fopen_index(archive, index, 0));
  if (!entry) fail("cannot open an entry: " + std::string(zip_strerror(archive)));
  FileDescriptor out(::open(target.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC,
                            S_IRUSR | S_IWUSR));
  if (out.get() < 0) fail(std::string("cannot write a temporary file: ") + std::strerror(errno));
  std::vector<char> chunk(kChunkBytes);
  std::uint64_t written = 0;
  for (;;) {
    const zip_int64_t got = zip_fread(entry.get(), chunk.data(), chunk.size());
    if (got < 0) {
      fail("damaged entry: " + std::string(zip_file_strerror(entry.get())));
    }
    if (got == 0) break;
    written += static_cast<std::uint64_t>(got);
    if (written > declared) fail("an entry inflates to more than its declared size");
    if (written > allowed) fail("the archive inflates beyond the limit of uncompressed bytes");
    const char* data = chunk.data();
    std::size_t left = static_cast<std::size_t>(got);
    while (left > 0) {
      const ssize_t put = ::write(out.get(), data, left);
      if (put < 0) {
        if (errno == EINTR) continue;
        fail(std::string("cannot write a temporary file: ") + std::strerror(errno));
      }
      data += put;
      left -= static_cast<std::size_t>(put);
    }
  }
  if (written != declared) fail("an entry is shorter than its declared size");
  if (::close(out.release()) != 0) {
    fail(std::string("cannot write a temporary file: ") + std::strerror(errno));
  }
  return written;
}

std::string ratio_text(double ratio) {
  std::ostringstream out;
  out.precision(4);
  out << ratio;
  return out.str();
}

}  // namespace

ExtractedZip::ExtractedZip(ExtractedZip&& other) noexcept
    : files(other.files), bytes(other.bytes), warnings(std::move(other.warnings)),
      folder_(std::move(other.folder_)) {
  other.folder_.clear();
}

ExtractedZip& ExtractedZip::operator=(ExtractedZip&& other) noexcept {
  if (this != &other) {
    std::error_code ignored;
    if (!folder_.empty()) std::filesystem::remove_all(folder_, ignored);
    folder_ = std::move(other.folder_);
    other.folder_.clear();
    files = other.files;
    bytes = other.bytes;
    warnings = std::move(other.warnings);
  }
  return *this;
}

ExtractedZip::~ExtractedZip() {
  if (folder_.empty()) return;
  std::error_code ignored;
  std::filesystem::remove_all(folder_, ignored);
}

bool is_zip_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::array<char, 4> head{};
  if (!in.read(head.data(), head.size())) return false;
  return head[0] == 'P' && head[1] == 'K' &&
         ((head[2] == 3 && head[3] == 4) || (head[2] == 5 && head[3] == 6));
}

ExtractedZip extract_zip(const std::filesystem::path& archive_path, const ZipLimits& limits) {
  int code = 0;
  std::unique_ptr<zip_t, ArchiveCloser> archive(
      zip_open(archive_path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &code));
  if (!archive) fail("cannot open: " + zip_reason(code));
  const zip_int64_t count = zip_get_num_entries(archive.get(), 0);
  if (count < 0) fail("unreadable central directory");
  if (static_cast<std::uint64_t>(count) > limits.max_entries) {
    fail(std::to_string(count) + " entries, more than the limit of " +
         std::to_string(limits.max_entries));
  }

  // Every declared size is checked before a byte is written.
  std::uint64_t declared_total = 0;
  std::vector<zip_uint64_t> regular;
  std::size_t directories = 0, links = 0, encrypted = 0;
  std::vector<std::uint64_t> sizes;
  for (zip_uint64_t index = 0; index < static_cast<zip_uint64_t>(count); ++index) {
    zip_stat_t stat;
    zip_stat_init(&stat);
    if (zip_stat_index(archive.get(), index, 0, &stat) != 0) {
      fail("unreadable entry: " + std::string(zip_strerror(archive.get())));
    }
    const bool has_sizes = (stat.valid & ZIP_STAT_SIZE) && (stat.valid & ZIP_STAT_COMP_SIZE);
    if (!has_sizes) fail("an entry without sizes");
    const std::size_t name_length = stat.name != nullptr ? std::strlen(stat.name) : 0;
    if (name_length > 0 && stat.name[name_length - 1] == '/') {
      ++directories;
      continue;
    }
    if (is_symbolic_link(archive.get(), index)) {
      ++links;
      continue;
    }
    if ((stat.valid & ZIP_STAT_ENCRYPTION_METHOD) && stat.encryption_method != ZIP_EM_NONE) {
      ++encrypted;
      continue;
    }
    if (stat.size > limits.max_total_bytes - std::min(declared_total, limits.max_total_bytes)) {
      fail("its entries declare more than the limit of " +
           std::to_string(limits.max_total_bytes >> 20) + " MiB uncompressed");
    }
    declared_total += stat.size;
    if (stat.size >= limits.ratio_check_bytes) {
      const double ratio = static_cast<double>(stat.size) /
                           static_cast<double>(std::max<zip_uint64_t>(stat.comp_size, 1));
      if (ratio > limits.max_compression_ratio) {
        fail("an entry compressed " + ratio_text(ratio) + " : 1, more than the limit of " +
             ratio_text(limits.max_compression_ratio) + " : 1 (a zip bomb?)");
      }
    }
    regular.push_back(index);
    sizes.push_back(stat.size);
  }

  ExtractedZip extracted(make_private_folder());
  std::uint64_t total = 0;
  for (std::size_t n = 0; n < regular.size(); ++n) {
    const std::filesystem::path target = extracted.folder() / entry_file_name(n + 1);
    total += inflate_entry(archive.get(), regular[n], sizes[n], limits.max_total_bytes - total,
                           target);
    ++extracted.files;
  }
  extracted.bytes = total;
  if (directories + links + encrypted > 0) {
    std::string skipped = "skipped in the ZIP archive:";
    if (links > 0) skipped += " " + std::to_string(links) + " symbolic links";
    if (encrypted > 0) skipped += " " + std::to_string(encrypted) + " encrypted entries";
    if (directories > 0) skipped += " " + std::to_string(directories) + " folder entries";
    if (links + encrypted > 0) extracted.warnings.push_back(skipped);
  }
  return extracted;
}

}  // namespace typemerge::zip_input
