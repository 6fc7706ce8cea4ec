// plan_studies: from one scan of a study tree to the list of studies a batch converts.
//
// A study is every series sharing a StudyInstanceUID, wherever its files lie under the root.
// Per study one series is chosen by the rule of `typemerge info` (a usable CT volume, not a
// localizer; most slices, then the thinnest step), restricted by an optional filter. Each study
// gets an output name from a pattern; names are sanitised so they can never leave the output
// folder, never start with '.', never collide with each other, and never carry a folder name
// that spells the patient's name or ID.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "dicom/series_scan.h"

namespace typemerge::app {

// Restricts the series a study may be meshed from. Empty members do not restrict.
struct SeriesFilter {
  std::string description_regex;  // searched case-insensitively in SeriesDescription
  std::string kernel_regex;       // searched case-insensitively in ConvolutionKernel
  std::optional<double> min_thickness_mm;  // SliceThickness, else the slice step
  std::optional<double> max_thickness_mm;

  bool empty() const;
  // Throws std::invalid_argument for a malformed regular expression.
  bool accepts(const dicom::SeriesInfo& series) const;
};

// What a study is converted from: a series of the DICOM scan, or one file that is a study by
// itself (batch_files.h).
enum class StudySource { dicom, nifti, nrrd, segmentation_nrrd, dicom_seg, zip };

struct StudyPlan {
  StudySource source = StudySource::dicom;
  std::filesystem::path input_file;  // file studies: the file, relative to the root
  // NIfTI and NRRD studies: the header marks labels (NIfTI label intent) or the samples are
  // unsigned integers; such files are converted in label mode under --labels.
  bool label_map = false;
  std::string study_id;           // 12 hex digits of a hash of the StudyInstanceUID
  std::filesystem::path folder;   // relative to the root: the deepest folder holding all its files
  std::string shown_folder;       // `folder` for outputs: components spelling patient data masked
  std::vector<std::filesystem::path> files;  // every file of the study (all series), sorted
  std::string series_id;          // the chosen series; empty when none could be chosen
  std::string refusal;            // why none was chosen
  std::uint64_t voxels = 0;       // of the chosen series' volume
  std::array<std::uint64_t, 3> grid_size{};  // its grid (columns, rows, slices)
  std::array<double, 3> spacing_mm{};         // and spacing
  bool int16_samples = false;  // and it loads as int16 samples (for the memory estimate)
  std::string output_name;        // relative folder under the output root ('/'-separated)
};

// Placeholders of an output-name pattern: {folder} (the study's relative folder), {study}
// (study_id), {series} (chosen series id).
inline constexpr const char* kDefaultNamePattern = "{folder}";

// Given one file of a study, the values that identify its patient (name parts, IDs; see
// dicom::patient_identifiers).
using IdentifyingValues = std::function<std::vector<std::string>(const std::filesystem::path&)>;

// A folder component containing one of `identifying`'s values for its study is replaced by
// "study-<id>"; without `identifying` no folder is masked.
std::vector<StudyPlan> plan_studies(const dicom::FolderScan& scan, const SeriesFilter& filter,
                                    const std::string& name_pattern,
                                    const IdentifyingValues& identifying = {});

// `pattern` filled in for `study` (its shown_folder, study_id, series_id) and made safe as
// plan_studies does: sanitised components, none ending like an output file, never empty.
std::string study_output_name(const std::string& pattern, const StudyPlan& study);

// Whether a path component spells one of `values` (letters and digits compared
// case-insensitively; values shorter than 3 characters never match).
bool spells_identifier(const std::string& component, const std::vector<std::string>& values);

// The study id of a StudyInstanceUID (stable, non-identifying).
std::string study_id_of(const std::string& study_uid);

// One path component made safe: characters outside [A-Za-z0-9._+-] become '_', a leading '.'
// becomes '_', "." and ".." and "" become "_", at most 96 characters.
std::string sanitise_component(const std::string& component);

// Deterministic share of studies for shard k of n (1-based): by the study id, so a study keeps
// its shard when others are added or removed.
bool in_shard(const std::string& study_id, int k, int n);

}  // namespace typemerge::app
