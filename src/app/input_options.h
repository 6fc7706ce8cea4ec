// Options shared by every command that reads a DICOM folder, bound once to CLI11.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>

#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "app/input_kind.h"
#include "app/volume_file_input.h"

namespace CLI {
class App;
}

namespace typemerge::app {

struct InputOptions {
  std::string input;
  bool resample_spacing = false;
  bool allow_non_ct = false;
  bool follow_symlinks = false;
  int max_depth = 16;

  dicom::ScanOptions scan_options() const;
};

// `required`: whether DIR must be given (batch --merge-summaries needs none).
void add_input_options(CLI::App& command, InputOptions& options, bool required = true);

// The folder scanned, the series chosen and its volume loaded; what volume and convert share.
// A NIfTI or NRRD file (input_kind) loads as a scan of one series: id "nifti" or "nrrd", no
// modality or description, its values in `loaded` (min_hu/max_hu the value range, whatever
// the units).
struct LoadedInput {
  InputKind kind = InputKind::dicom;
  dicom::FolderScan scan;
  const dicom::SeriesInfo* series = nullptr;  // points into scan
  dicom::LoadedSeries loaded;
};

// What is known of the input before its pixels are read: enough for the memory estimate.
struct InputShape {
  std::string id;
  std::array<std::uint64_t, 3> size{};
  std::array<double, 3> spacing{};
  // The volume will hold int16 samples (dicom::loads_as_int16; for a NIfTI or NRRD file,
  // VolumeFileShape::int16_samples).
  bool int16_samples = false;
  std::array<std::uint64_t, 3> grid_size() const { return size; }
  std::array<double, 3> spacing_mm() const { return spacing; }
};

// Throws CommandError (input refused) with the loader's one-line reason.
dicom::FolderScan scan_input(const InputOptions& options);
// `before_load` sees the chosen series before its pixels are read (and may refuse it by throwing).
LoadedInput load_input(const InputOptions& options, const std::string& series_id,
                       const std::function<void(const InputShape&)>& before_load = {});

// Scans the folder and picks the series: `series_id` if given, else the default one.
// Throws CommandError (input refused) with the reason when there is none to load.
const dicom::SeriesInfo& select_series(const dicom::FolderScan& scan, const std::string& series_id);

}  // namespace typemerge::app
