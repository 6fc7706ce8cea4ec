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
  command.add_option("DIR", options.input, "DICOM folder (searched recursively) or file")
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

LoadedInput load_input(const InputOptions& options, const std::string& series_id,
                       const std::function<void(const dicom::SeriesInfo&)>& before_load) {
  LoadedInput input;
  input.scan = scan_input(options);
  input.series = &select_series(input.scan, series_id);
  if (before_load) before_load(*input.series);
  try {
    input.loaded = dicom::load_series(*input.series);
  } catch (const dicom::LoadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  return input;
}

}  // namespace typemerge::app
