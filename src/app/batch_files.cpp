#include "app/batch_files.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>
#include <tuple>

#include "app/exit_codes.h"
#include "app/volume_file_input.h"
#include "nrrd/nrrd_header.h"
#include "seg/seg_reader.h"
#include "zip_input/zip_extract.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

bool ends_with(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The file name without the extension that marks its kind ("ct.nii.gz" → "ct").
std::string stem_of(const std::string& name) {
  const std::string low = lower(name);
  for (const char* suffix : {".nii.gz", ".seg.nrrd", ".nii", ".nrrd", ".nhdr", ".zip", ".dcm"}) {
    if (ends_with(low, suffix) && low.size() > std::string(suffix).size()) {
      return name.substr(0, name.size() - std::string(suffix).size());
    }
  }
  return name;
}

InputKind input_kind_of(StudySource source) {
  switch (source) {
    case StudySource::nifti: return InputKind::nifti;
    case StudySource::nrrd:
    case StudySource::segmentation_nrrd: return InputKind::nrrd;
    case StudySource::dicom_seg: return InputKind::seg;
    default: return InputKind::dicom;
  }
}

// A detached NRRD's data file (its content is part of the study's key); nullopt when the
// header names none or cannot be read (convert then gives the reason).
std::optional<fs::path> nrrd_data_file(const fs::path& header_file) {
  std::ifstream in(header_file, std::ios::binary);
  std::string text(64 * 1024, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  try {
    const nrrd::NrrdHeader header = nrrd::parse_nrrd_header(text);
    if (header.data_file.empty()) return std::nullopt;
    const fs::path data = header_file.parent_path() / header.data_file;
    std::error_code error;
    if (!fs::is_regular_file(data, error)) return std::nullopt;
    return data;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// Whether `ancestor` is `path` or one of its parent folders (both relative to the root).
bool contains(const fs::path& ancestor, const fs::path& path) {
  auto a = ancestor.begin();
  for (auto p = path.begin(); a != ancestor.end(); ++a, ++p) {
    if (p == path.end() || *a != *p) return false;
  }
  return true;
}

// The file's path under the root as it may be shown (see batch_files.h).
std::string masked_path(const fs::path& relative, const StudyPlan& plan,
                        const std::vector<std::string>& identifying) {
  std::vector<std::string> parts;
  for (const fs::path& part : relative.parent_path()) parts.push_back(part.string());
  parts.push_back(stem_of(relative.filename().string()));
  std::string shown;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const bool last = i + 1 == parts.size();
    std::string part = spells_identifier(parts[i], identifying)
                           ? (last ? std::string(source_name(plan.source)) : "study") + "-" +
                                 plan.study_id
                           : without_digit_runs(parts[i]);
    if (!shown.empty()) shown += "/";
    shown += part;
  }
  return shown;
}

}  // namespace

const char* source_name(StudySource source) {
  switch (source) {
    case StudySource::dicom: return "dicom";
    case StudySource::nifti: return "nifti";
    case StudySource::nrrd: return "nrrd";
    case StudySource::segmentation_nrrd: return "seg.nrrd";
    case StudySource::dicom_seg: return "seg";
    case StudySource::zip: return "zip";
  }
  return "?";
}

std::string without_digit_runs(const std::string& component) {
  auto digit = [&](std::size_t i) {
    return i < component.size() && std::isdigit(static_cast<unsigned char>(component[i]));
  };
  auto separator = [&](std::size_t i) {
    return i < component.size() && std::string_view("-_.:").find(component[i]) != std::string::npos;
  };
  std::string out;
  std::size_t i = 0;
  while (i < component.size()) {
    if (!digit(i)) {
      out += component[i++];
      continue;
    }
    // A run: digits, joined by single separators to groups of two digits or more.
    std::size_t end = i, digits = 0;
    while (true) {
      while (digit(end)) {
        ++end;
        ++digits;
      }
      if (separator(end) && digit(end + 1) && digit(end + 2)) {
        ++end;
        continue;
      }
      break;
    }
    out += digits >= 6 ? std::string("N") : component.substr(i, end - i);
    i = end;
  }
  return out;
}

std::optional<StudySource> file_study_source(const fs::path& file) {
  const std::string name = lower(file.filename().string());
  if (ends_with(name, ".nii") || ends_with(name, ".nii.gz")) return StudySource::nifti;
  if (ends_with(name, ".nrrd") || ends_with(name, ".nhdr")) return StudySource::nrrd;
  if (seg::is_seg_file(file)) return StudySource::dicom_seg;
  if (zip_input::is_zip_file(file)) return StudySource::zip;
  return std::nullopt;
}

void add_file_studies(const dicom::FolderScan& scan, const std::string& name_pattern,
                      const IdentifyingValues& identifying, std::vector<StudyPlan>& plans) {
  std::error_code error;
  // ROOT may be one such file: its scan lists it by its name alone.
  const bool root_is_folder = fs::is_directory(scan.root, error);
  const std::size_t dicom_studies = plans.size();
  std::vector<StudyPlan> found;
  for (const dicom::SkippedFile& skipped : scan.skipped) {
    // Damaged DICOM and unusable CT slices are accounted as folders (batch_folders.h).
    if (skipped.kind == dicom::FileKind::unreadable || skipped.kind == dicom::FileKind::ct_image) {
      continue;
    }
    const fs::path file = root_is_folder ? scan.root / skipped.path : scan.root;
    std::optional<StudySource> source = file_study_source(file);
    if (!source) continue;
    StudyPlan plan;
    plan.source = *source;
    plan.input_file = skipped.path;
    plan.study_id = study_id_of("file:" + skipped.path.lexically_normal().generic_string());
    plan.folder = skipped.path.parent_path();
    plan.files.push_back(file);
    if (plan.source == StudySource::nrrd) {
      if (const auto data = nrrd_data_file(file)) plan.files.push_back(*data);
    }
    if (plan.source != StudySource::zip) {
      try {
        const VolumeFileShape shape = read_volume_file_shape(file, input_kind_of(plan.source));
        if (plan.source == StudySource::nrrd && shape.segmentation) {
          plan.source = StudySource::segmentation_nrrd;
        }
        using volume_file::SampleType;
        plan.label_map = shape.segmentation || shape.type == SampleType::uint8 ||
                         shape.type == SampleType::uint16 || shape.type == SampleType::uint32;
        plan.grid_size = {static_cast<std::uint64_t>(shape.size.nx),
                          static_cast<std::uint64_t>(shape.size.ny),
                          static_cast<std::uint64_t>(shape.size.nz)};
        plan.spacing_mm = shape.spacing_mm();
        plan.int16_samples = shape.int16_samples;
        plan.voxels = plan.grid_size[0] * plan.grid_size[1] * plan.grid_size[2] * shape.layers;
      } catch (const CommandError& refused) {
        plan.refusal = std::string(source_name(plan.source)) + " file: " + refused.message;
      }
    }
    if (plan.refusal.empty()) plan.series_id = source_name(plan.source);

    // Values to keep out of the name: the SEG's own, and those of the DICOM studies around.
    std::vector<std::string> values;
    if (identifying) {
      if (plan.source == StudySource::dicom_seg) values = identifying(file);
      for (std::size_t d = 0; d < dicom_studies; ++d) {
        const StudyPlan& study = plans[d];
        if (study.files.empty()) continue;
        if (contains(study.folder, plan.folder) || contains(plan.folder, study.folder)) {
          const auto more = identifying(study.files.front());
          values.insert(values.end(), more.begin(), more.end());
        }
      }
    }
    plan.shown_folder = masked_path(skipped.path, plan, values);
    plan.output_name = study_output_name(name_pattern, plan);
    found.push_back(std::move(plan));
  }

  // Names colliding with a DICOM study's or with each other get the study id appended
  // (compared case-insensitively, for case-insensitive file systems).
  std::map<std::string, int> uses;
  for (const StudyPlan& plan : plans) ++uses[lower(plan.output_name)];
  for (const StudyPlan& plan : found) ++uses[lower(plan.output_name)];
  for (StudyPlan& plan : found) {
    if (uses[lower(plan.output_name)] > 1) plan.output_name += "-" + plan.study_id;
  }
  for (StudyPlan& plan : found) plans.push_back(std::move(plan));
  std::sort(plans.begin(), plans.end(), [](const StudyPlan& a, const StudyPlan& b) {
    return std::tie(a.output_name, a.study_id) < std::tie(b.output_name, b.study_id);
  });
}

}  // namespace typemerge::app
