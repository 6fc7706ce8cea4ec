#include "app/input_options.h"

#include <CLI/CLI.hpp>

#include <map>

#include "app/exit_codes.h"
#include "zip_input/zip_extract.h"

namespace typemerge::app {

dicom::ScanOptions InputOptions::scan_options() const {
  dicom::ScanOptions options;
  options.max_depth = max_depth;
  options.follow_symlinks = follow_symlinks;
  options.header.allow_non_ct_modality = allow_non_ct;
  options.geometry.spacing =
      resample_spacing ? dicom::SpacingPolicy::resample : dicom::SpacingPolicy::refuse;
  return options;
}

void add_input_options(CLI::App& command, InputOptions& options, bool required) {
  command.add_option("DIR", options.input,
                     "DICOM folder (searched recursively) or file, or a NIfTI (.nii, .nii.gz) "
                     "or NRRD (.nrrd, .seg.nrrd, .nhdr) file")
      ->required(required);
  command.add_flag("--resample-spacing", options.resample_spacing,
                   "Accept series with missing slices or uneven spacing by resampling them "
                   "linearly at their smallest slice step (recorded as a warning)");
  command.add_flag("--allow-non-ct", options.allow_non_ct,
                   "Accept monochrome images of other modalities (MR, PT, ...) as volumes");
  command.add_flag("--follow-symlinks", options.follow_symlinks,
                   "Follow symbolic links to folders while searching");
  command.add_option("--max-depth", options.max_depth, "Folder levels searched below DIR")
      ->check(CLI::Range(1, 256));
}

const dicom::SeriesInfo& select_series(const dicom::FolderScan& scan,
                                       const std::string& series_id) {
  if (!series_id.empty()) {
    const dicom::SeriesInfo* found = scan.find(series_id);
    if (found == nullptr) {
      throw CommandError{kExitInputRefused, "no series " + series_id + " in " +
                                                scan.root.string() + " (see `typemerge info`)"};
    }
    return *found;
  }
  if (!scan.default_series) {
    std::string reason = "no usable CT series in " + scan.root.string();
    for (const auto& series : scan.series) {
      if (series.role == dicom::SeriesRole::volume && !series.geometry.ok()) {
        reason += "; " + series.id + ": " + series.geometry.error;
        break;
      }
    }
    if (scan.series.empty()) {
      reason += " (" + std::to_string(scan.files_seen) + " files, " +
                std::to_string(scan.skipped.size()) + " skipped; see `typemerge info`)";
    }
    throw CommandError{kExitInputRefused, reason};
  }
  return scan.series[*scan.default_series];
}

namespace {

// A ZIP archive of DICOM files is scanned as the private folder its entries are extracted to
// (zip_input/zip_extract.h), kept until the process ends and then removed; anything else as
// it is.
const zip_input::ExtractedZip* extracted_zip(const std::string& input) {
  if (!zip_input::is_zip_file(input)) return nullptr;
  static std::map<std::string, zip_input::ExtractedZip> extracted;
  auto found = extracted.find(input);
  if (found == extracted.end()) {
    try {
      found = extracted.emplace(input, zip_input::extract_zip(input)).first;
    } catch (const zip_input::ZipError& error) {
      throw CommandError{kExitInputRefused, error.what()};
    }
  }
  return &found->second;
}

}  // namespace

dicom::FolderScan scan_input(const InputOptions& options) {
  const zip_input::ExtractedZip* zip = extracted_zip(options.input);
  try {
    dicom::FolderScan scan =
        dicom::scan_folder(zip != nullptr ? zip->folder() : std::filesystem::path(options.input),
                           options.scan_options());
    if (zip != nullptr) {
      scan.warnings.insert(scan.warnings.end(), zip->warnings.begin(), zip->warnings.end());
    }
    return scan;
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
}

namespace {

// A NIfTI or NRRD file as a scan of one series (see LoadedInput).
LoadedInput load_volume_file_input(const InputOptions& options, const std::string& series_id,
                                   InputKind kind,
                                   const std::function<void(const InputShape&)>& before_load) {
  if (!series_id.empty()) {
    throw CommandError{kExitUsage, "--series applies to DICOM folders, not to a " +
                                       std::string(to_string(kind)) + " file"};
  }
  const VolumeFileShape shape = read_volume_file_shape(options.input, kind);
  if (shape.layers > 1) {
    throw CommandError{kExitInputRefused,
                       "this " + std::string(to_string(kind)) + " file holds " +
                           std::to_string(shape.layers) +
                           " layers of segments: convert it in label mode (--labels all)"};
  }
  LoadedInput input;
  input.kind = kind;
  dicom::SeriesInfo series;
  series.id = kind == InputKind::nifti ? "nifti" : kind == InputKind::seg ? "seg" : "nrrd";
  series.geometry.slice_step_mm = shape.geometry.spacing(2);
  series.geometry.index_to_patient = shape.geometry;
  if (before_load) {
    before_load({series.id,
                 {static_cast<std::uint64_t>(shape.size.nx), static_cast<std::uint64_t>(shape.size.ny),
                  static_cast<std::uint64_t>(shape.size.nz)},
                 shape.spacing_mm(), shape.int16_samples});
  }
  VolumeFile file = read_volume_file(options.input, kind);
  input.scan.series.push_back(std::move(series));
  input.scan.default_series = 0;
  input.scan.files_seen = 1;
  input.series = &input.scan.series.front();
  input.loaded.series_id = input.series->id;
  input.loaded.volume = std::move(file.content.layers.front());
  input.loaded.min_hu = file.values.min;
  input.loaded.max_hu = file.values.max;
  input.loaded.warnings = std::move(file.warnings);
  return input;
}

}  // namespace

LoadedInput load_input(const InputOptions& options, const std::string& series_id,
                       const std::function<void(const InputShape&)>& before_load) {
  if (const InputKind kind = input_kind(options.input); kind != InputKind::dicom) {
    return load_volume_file_input(options, series_id, kind, before_load);
  }
  LoadedInput input;
  input.scan = scan_input(options);
  input.series = &select_series(input.scan, series_id);
  if (before_load) {
    before_load({input.series->id, input.series->grid_size(), input.series->spacing_mm(),
                 dicom::loads_as_int16(*input.series)});
  }
  try {
    input.loaded = dicom::load_series(*input.series);
  } catch (const dicom::LoadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  return input;
}

}  // namespace typemerge::app
