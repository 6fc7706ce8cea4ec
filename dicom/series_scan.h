// scan_folder: from a folder tree to the series it holds, each classified and checked.
//
// Every file is classified (CT image, other image, non-image DICOM, not DICOM, unreadable);
// CT frames are grouped into series by study, series, frame of reference, image size, pixel
// spacing, image type and orientation. Localizers (ImageType LOCALIZER, or slices whose
// orientation differs from the rest of their series) become series of their own that are
// never offered as volumes. Nothing is written into the input tree, and one bad file never
// stops the scan of the others.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dicom/header_reader.h"
#include "dicom/slice_geometry.h"
#include "dicom/slice_header.h"

namespace typemerge::dicom {

struct ScanOptions {
  int max_depth = 16;             // folder levels below the root
  bool follow_symlinks = false;
  std::size_t max_files = 200000;
  HeaderReadOptions header;
  GeometryOptions geometry;
};

struct SkippedFile {
  std::filesystem::path path;  // relative to the scanned root
  FileKind kind = FileKind::not_dicom;
  std::string reason;
  std::string refused_modality;  // see HeaderReadResult
};

enum class SeriesRole {
  volume,     // candidate for a volume
  localizer,  // scout / localizer: never stacked
};

struct SeriesInfo {
  std::string id;  // short, non-identifying, stable: derived from a hash of the UIDs
  std::string description;
  std::string modality;
  std::string convolution_kernel;
  std::int32_t series_number = 0;
  SeriesRole role = SeriesRole::volume;
  std::string role_reason;
  std::vector<SliceHeader> slices;  // in the order given by geometry.order
  std::uint16_t rows = 0, columns = 0;
  StackGeometry geometry;
  std::vector<std::string> warnings;  // header warnings of its files

  bool usable() const { return role == SeriesRole::volume && geometry.ok(); }
  // Its grid: voxels along columns, rows and slices (none when refused), and their spacing
  // in mm (the pixel spacing of its first slice, 1 mm when absent, and the slice step).
  std::array<std::uint64_t, 3> grid_size() const {
    return {columns, rows,
            static_cast<std::uint64_t>(geometry.output_slices > 0 ? geometry.output_slices : 0)};
  }
  // Voxels of the volume it loads to.
  std::uint64_t voxels() const {
    const auto size = grid_size();
    return size[0] * size[1] * size[2];
  }
  std::array<double, 3> spacing_mm() const {
    const auto& pixel = slices.empty() ? std::nullopt : slices.front().pixel_spacing;
    return {pixel ? (*pixel)[1] : 1.0, pixel ? (*pixel)[0] : 1.0, geometry.slice_step_mm};
  }
};

struct FolderScan {
  std::filesystem::path root;
  std::size_t files_seen = 0;
  std::vector<SeriesInfo> series;     // sorted by series number, then id
  std::vector<SkippedFile> skipped;   // sorted by path
  std::vector<std::string> warnings;  // scan-level: depth limit, file limit, unreadable folders
  std::optional<std::size_t> default_series;  // index into series

  const SeriesInfo* find(const std::string& id) const;
};

// Folder or single file. Throws std::runtime_error when the root does not exist.
FolderScan scan_folder(const std::filesystem::path& root, const ScanOptions& options);

// Groups already-read headers into series (exposed for tests and fuzzing).
std::vector<SeriesInfo> group_into_series(std::vector<SliceHeader> headers,
                                          const GeometryOptions& options);

// The CT series with the most slices among the usable ones; ties: the thinnest spacing,
// then the lowest series number and id (so the choice is stable).
std::optional<std::size_t> choose_default_series(const std::vector<SeriesInfo>& series);

// The same rule among the usable series for which `eligible` is true (batch filters).
std::optional<std::size_t> choose_series(const std::vector<SeriesInfo>& series,
                                         const std::function<bool(const SeriesInfo&)>& eligible);

// The same rule among series[i], i in `candidates` (increasing), e.g. one study's series of
// a large tree, without visiting the others.
std::optional<std::size_t> choose_series(const std::vector<SeriesInfo>& series,
                                         std::span<const std::size_t> candidates,
                                         const std::function<bool(const SeriesInfo&)>& eligible);

}  // namespace typemerge::dicom
