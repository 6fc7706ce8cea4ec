#include "app/batch_plan.h"

#include <xxhash.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <regex>
#include <stdexcept>

#include "dicom/series_loader.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;

bool search_icase(const std::string& pattern, const std::string& text) {
  try {
    return std::regex_search(text, std::regex(pattern, std::regex::ECMAScript | std::regex::icase));
  } catch (const std::regex_error& error) {
    throw std::invalid_argument("malformed regular expression '" + pattern + "': " + error.what());
  }
}

// Lower-case letters and digits only: "DOE^JOHN" and "doe_john" compare equal.
std::string normalised(const std::string& text) {
  std::string out;
  for (unsigned char c : text) {
    if (std::isalnum(c)) out += static_cast<char>(std::tolower(c));
  }
  return out;
}

bool looks_identifying(const std::string& component, const std::vector<std::string>& values) {
  const std::string haystack = normalised(component);
  for (const std::string& value : values) {
    const std::string needle = normalised(value);
    // Shorter values (initials, "1") would match almost any folder name.
    if (needle.size() >= 3 && haystack.find(needle) != std::string::npos) return true;
  }
  return false;
}

fs::path common_folder(const std::vector<fs::path>& relative_files) {
  if (relative_files.empty()) return {};
  const fs::path first = relative_files.front().parent_path();
  std::vector<fs::path> common(first.begin(), first.end());
  for (const fs::path& file : relative_files) {
    const fs::path parent = file.parent_path();
    std::size_t shared = 0;
    for (auto part = parent.begin(); part != parent.end() && shared < common.size(); ++part) {
      if (*part != common[shared]) break;
      ++shared;
    }
    common.resize(shared);
  }
  fs::path folder;
  for (const fs::path& part : common) folder /= part;
  return folder;
}

std::string replace_all(std::string text, const std::string& from, const std::string& to) {
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
  return text;
}

// Output names already used as files inside a study's folder must not be folder names too.
bool ends_like_output_file(const std::string& component) {
  for (const char* suffix : {".stl", ".png", ".json", ".ply", ".obj", ".partial"}) {
    const std::string s = suffix;
    if (component.size() >= s.size() &&
        std::equal(s.rbegin(), s.rend(), component.rbegin(),
                   [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); })) {
      return true;
    }
  }
  return false;
}

// The study's folder as it may be shown: components that spell a patient identifier become
// "study-<id>"; the rest stay as they are.
std::string masked_folder(const StudyPlan& study, const std::vector<std::string>& identifying) {
  if (study.folder.empty()) return "study-" + study.study_id;
  std::string shown;
  for (const fs::path& part : study.folder) {
    if (!shown.empty()) shown += "/";
    shown += looks_identifying(part.string(), identifying) ? "study-" + study.study_id
                                                           : part.string();
  }
  return shown;
}

std::string output_name(const std::string& pattern, const StudyPlan& study) {
  std::string name = replace_all(pattern, "{folder}", study.shown_folder);
  name = replace_all(name, "{study}", study.study_id);
  name = replace_all(name, "{series}", study.series_id.empty() ? "none" : study.series_id);
  std::string safe;
  std::size_t start = 0;
  while (start <= name.size()) {
    std::size_t end = name.find_first_of("/\\", start);
    if (end == std::string::npos) end = name.size();
    const std::string raw = name.substr(start, end - start);
    start = end + 1;
    if (raw.empty()) continue;  // "a//b", leading or trailing separators
    std::string component = sanitise_component(raw);
    if (ends_like_output_file(component)) component += "_";
    if (!safe.empty()) safe += "/";
    safe += component;
  }
  return safe.empty() ? "study-" + study.study_id : safe;
}

std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

std::string refusal_reason(const std::vector<const dicom::SeriesInfo*>& series,
                           const SeriesFilter& filter) {
  bool any_volume = false;
  bool any_usable = false;
  std::string geometry_error;
  for (const dicom::SeriesInfo* info : series) {
    if (info->role != dicom::SeriesRole::volume) continue;
    any_volume = true;
    if (info->usable()) any_usable = true;
    if (!info->geometry.ok() && geometry_error.empty()) {
      geometry_error = "series " + info->id + ": " + info->geometry.error;
    }
  }
  if (!any_volume) return "only localizer images, no CT volume";
  if (any_usable && !filter.empty()) return "no usable series matches the series filter";
  return geometry_error.empty() ? "no usable CT series" : geometry_error;
}

}  // namespace

bool SeriesFilter::empty() const {
  return description_regex.empty() && kernel_regex.empty() && !min_thickness_mm &&
         !max_thickness_mm;
}

bool SeriesFilter::accepts(const dicom::SeriesInfo& series) const {
  if (!description_regex.empty() && !search_icase(description_regex, series.description)) {
    return false;
  }
  if (!kernel_regex.empty() && !search_icase(kernel_regex, series.convolution_kernel)) {
    return false;
  }
  if (min_thickness_mm || max_thickness_mm) {
    double thickness = series.geometry.slice_step_mm;
    if (!series.slices.empty() && series.slices.front().slice_thickness) {
      thickness = *series.slices.front().slice_thickness;
    }
    if (min_thickness_mm && thickness < *min_thickness_mm - 1e-6) return false;
    if (max_thickness_mm && thickness > *max_thickness_mm + 1e-6) return false;
  }
  return true;
}

std::string study_output_name(const std::string& pattern, const StudyPlan& study) {
  return output_name(pattern, study);
}

bool spells_identifier(const std::string& component, const std::vector<std::string>& values) {
  return looks_identifying(component, values);
}

std::string study_id_of(const std::string& study_uid) {
  char text[17];
  std::snprintf(text, sizeof text, "%012llx",
                static_cast<unsigned long long>(XXH3_64bits(study_uid.data(), study_uid.size()) >>
                                                16));
  return text;
}

std::string sanitise_component(const std::string& component) {
  if (component.empty() || component == "." || component == "..") return "_";
  std::string out;
  for (unsigned char c : component.substr(0, 96)) {
    out += (std::isalnum(c) || c == '.' || c == '_' || c == '+' || c == '-') ? static_cast<char>(c)
                                                                            : '_';
  }
  if (out.front() == '.') out.front() = '_';
  return out;
}

bool in_shard(const std::string& study_id, int k, int n) {
  const std::uint64_t hash = XXH3_64bits(study_id.data(), study_id.size());
  return static_cast<int>(hash % static_cast<std::uint64_t>(n)) == k - 1;
}

std::vector<StudyPlan> plan_studies(
    const dicom::FolderScan& scan, const SeriesFilter& filter, const std::string& name_pattern,
    const IdentifyingValues& identifying) {
  // std::map: studies in a stable order, whatever the order the scan met them in.
  std::map<std::string, std::vector<std::size_t>> series_by_study;
  for (std::size_t s = 0; s < scan.series.size(); ++s) {
    if (scan.series[s].slices.empty()) continue;
    series_by_study[scan.series[s].slices.front().study_uid].push_back(s);
  }
  std::error_code error;
  const bool root_is_folder = fs::is_directory(scan.root, error);

  std::vector<StudyPlan> plans;
  for (const auto& [study_uid, members] : series_by_study) {
    StudyPlan plan;
    plan.study_id = study_id_of(study_uid);
    std::vector<const dicom::SeriesInfo*> series;
    std::vector<fs::path> relative;
    for (std::size_t s : members) {
      series.push_back(&scan.series[s]);
      for (const auto& slice : scan.series[s].slices) {
        plan.files.push_back(slice.path);
        relative.push_back(root_is_folder ? slice.path.lexically_relative(scan.root)
                                          : slice.path.filename());
      }
    }
    std::sort(plan.files.begin(), plan.files.end());
    plan.files.erase(std::unique(plan.files.begin(), plan.files.end()), plan.files.end());
    plan.folder = common_folder(relative);

    const auto chosen = dicom::choose_series(
        scan.series, members, [&](const dicom::SeriesInfo& info) { return filter.accepts(info); });
    if (chosen) {
      const dicom::SeriesInfo& info = scan.series[*chosen];
      plan.series_id = info.id;
      plan.voxels = info.voxels();
      plan.grid_size = info.grid_size();
      plan.spacing_mm = info.spacing_mm();
      plan.int16_samples = dicom::loads_as_int16(info);
    } else {
      plan.refusal = refusal_reason(series, filter);
    }
    // Read from the first file of the study's first series, used for masking only.
    plan.shown_folder = masked_folder(
        plan, identifying ? identifying(scan.series[members.front()].slices.front().path)
                          : std::vector<std::string>{});
    plan.output_name = output_name(name_pattern, plan);
    plans.push_back(std::move(plan));
  }

  // Colliding names (compared case-insensitively, for case-insensitive file systems) all get
  // their study id appended: no study overwrites another, and the same tree gives the same
  // names on every run and in every shard (names are made before sharding).
  std::map<std::string, int> uses;
  for (const StudyPlan& plan : plans) ++uses[lower(plan.output_name)];
  for (StudyPlan& plan : plans) {
    if (uses[lower(plan.output_name)] > 1) plan.output_name += "-" + plan.study_id;
  }
  std::sort(plans.begin(), plans.end(), [](const StudyPlan& a, const StudyPlan& b) {
    return std::tie(a.output_name, a.study_id) < std::tie(b.output_name, b.study_id);
  });
  return plans;
}

}  // namespace typemerge::app
