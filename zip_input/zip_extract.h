// extract_zip: a ZIP archive of DICOM files (a "study.zip") → a private temporary folder the
// normal folder loader reads, removed again when the ExtractedZip goes out of scope.
//
// Why extraction and not reading in memory: the DICOM loader (dicom/series_scan.h,
// header_reader, pixel_reader) works on file paths — it reads headers lazily, reopens files
// for their pixels and bounds every read by the file's size. Feeding it memory buffers would
// mean a second code path through each step; extracting reuses the whole loader unchanged,
// so a ZIP converts byte for byte as its folder does. Extraction costs one sequential write of
// the uncompressed data (docs/inputs-seg-zip.md has the measurement).
//
// Guarantees:
// - Nothing is written outside the temporary folder: entries are written under numbered
//   names ("00000001.dcm", ...), never under their names in the archive, so no entry name
//   ("../x", "/etc/x", "C:\x", symbolic links) can reach another place, and no entry name or
//   folder from the archive appears in any file name or message.
// - The folder is made with mkdtemp (mode 0700) under the system temporary folder (TMPDIR),
//   its files with O_EXCL | O_NOFOLLOW (mode 0600), and removed with all it holds when the
//   ExtractedZip is destroyed, also when extraction throws.
// - Zip bombs are refused before or while a byte is written, by the limits below, checked on
//   the sizes the archive declares and again on the bytes actually inflated (a lying header
//   is caught when the data exceeds what it declared). Damaged archives (bad CRC, truncated,
//   inconsistent directory) are refused with libzip's reason.
// - Directories, symbolic links and encrypted entries are skipped (counted in warnings).
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace typemerge::zip_input {

// A CT study is a few thousand files; 100,000 leaves room for whole-body multi-series studies.
inline constexpr std::uint64_t kMaxEntries = 100000;
// Uncompressed bytes of all entries together: above the largest studies (a 2,000-slice
// 512 × 512 16-bit series is 1 GiB) and below what a temporary folder can usually take.
inline constexpr std::uint64_t kMaxTotalBytes = std::uint64_t{8} << 30;
// Uncompressed / compressed size per entry. Deflate's ceiling is about 1,032; DICOM CT slices
// compress 2–5×, mostly empty segmentation frames a few hundred times, a zip bomb's zeros
// about 1,000×. Only entries of at least kRatioCheckBytes are held to it (small files'
// ratios say nothing).
inline constexpr double kMaxCompressionRatio = 500.0;
inline constexpr std::uint64_t kRatioCheckBytes = std::uint64_t{1} << 20;

struct ZipLimits {
  std::uint64_t max_entries = kMaxEntries;
  std::uint64_t max_total_bytes = kMaxTotalBytes;
  double max_compression_ratio = kMaxCompressionRatio;
  std::uint64_t ratio_check_bytes = kRatioCheckBytes;
};

class ZipError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Owns the temporary folder; removes it on destruction. Move-only.
class ExtractedZip {
 public:
  ExtractedZip() = default;
  explicit ExtractedZip(std::filesystem::path folder) : folder_(std::move(folder)) {}
  ExtractedZip(ExtractedZip&& other) noexcept;
  ExtractedZip& operator=(ExtractedZip&& other) noexcept;
  ExtractedZip(const ExtractedZip&) = delete;
  ExtractedZip& operator=(const ExtractedZip&) = delete;
  ~ExtractedZip();

  const std::filesystem::path& folder() const { return folder_; }
  std::size_t files = 0;                  // entries written
  std::uint64_t bytes = 0;                // their uncompressed bytes
  std::vector<std::string> warnings;      // skipped entries, by kind and count

 private:
  std::filesystem::path folder_;
};

// Whether the file starts like a ZIP archive (a local file header or an empty archive's end
// record). Never throws.
bool is_zip_file(const std::filesystem::path& file);

// Throws ZipError with a one-line reason naming neither the archive nor an entry; the
// temporary folder is gone by then.
ExtractedZip extract_zip(const std::filesystem::path& archive, const ZipLimits& limits = {});

}  // namespace typemerge::zip_input
