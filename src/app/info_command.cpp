#include "app/info_command.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <ostream>

#include "app/exit_codes.h"
#include "app/volume_file_info.h"

namespace typemerge::app {
namespace {

using nlohmann::json;

std::string orientation_label(const dicom::SeriesInfo& series) {
  core::Vec3 row, col, normal;
  const auto& o = *series.slices.front().orientation;
  if (!dicom::orientation_frame(o, row, col, normal)) return "invalid";
  const double x = std::abs(normal[0]), y = std::abs(normal[1]), z = std::abs(normal[2]);
  const double largest = std::max({x, y, z});
  const char* plane = largest == z ? "axial" : largest == y ? "coronal" : "sagittal";
  return largest > 0.99 ? plane : std::string("oblique (near ") + plane + ")";
}

struct SeriesValues {
  std::optional<std::pair<float, float>> hu_range;
  std::vector<std::string> warnings;
  std::string error;
};

// Loading gives the value range and value warnings; it is what `volume` and `convert` do.
SeriesValues load_values(const dicom::SeriesInfo& series) {
  SeriesValues values;
  if (!series.usable()) return values;
  try {
    dicom::LoadedSeries loaded = dicom::load_series(series);
    values.hu_range = std::make_pair(loaded.min_hu, loaded.max_hu);
    values.warnings = loaded.warnings;
  } catch (const dicom::LoadError& error) {
    values.error = error.what();
  }
  return values;
}

std::string format(const char* pattern, double a, double b, double c) {
  char text[96];
  std::snprintf(text, sizeof text, pattern, a, b, c);
  return text;
}

json series_json(const dicom::SeriesInfo& series, const SeriesValues& values, bool is_default,
                 bool show_description) {
  const auto& g = series.geometry;
  json item = {
      {"id", series.id},
      {"modality", series.modality},
      {"kernel", series.convolution_kernel},
      {"series_number", series.series_number},
      {"role", series.role == dicom::SeriesRole::volume ? "volume" : "localizer"},
      {"slices", series.slices.size()},
      {"rows", series.rows},
      {"columns", series.columns},
      {"usable", series.usable() && values.error.empty()},
      {"default", is_default},
      {"orientation", orientation_label(series)},
      {"warnings", g.warnings},
  };
  if (show_description) item["description"] = series.description;
  if (!series.role_reason.empty()) item["role_reason"] = series.role_reason;
  if (!g.ok()) item["refusal"] = g.error;
  if (!values.error.empty()) item["refusal"] = values.error;
  if (g.ok()) {
    item["size"] = {series.columns, series.rows, g.output_slices};
    item["spacing_mm"] = {g.index_to_patient.spacing(0), g.index_to_patient.spacing(1),
                          g.slice_step_mm};
    item["tilt_degrees"] = g.tilt_degrees;
    item["origin_lps_mm"] = g.index_to_patient.origin;
    item["axes_lps_mm"] = g.index_to_patient.axes;
  }
  if (values.hu_range) item["hu_range"] = {values.hu_range->first, values.hu_range->second};
  for (const auto& w : values.warnings) {
    if (std::find(g.warnings.begin(), g.warnings.end(), w) == g.warnings.end()) {
      item["warnings"].push_back(w);
    }
  }
  return item;
}

void print_text(const dicom::FolderScan& scan, const std::vector<SeriesValues>& values,
                const InfoOptions& options, std::ostream& out) {
  out << scan.series.size() << " series in " << scan.files_seen << " files ("
      << scan.skipped.size() << " skipped)\n";
  for (std::size_t s = 0; s < scan.series.size(); ++s) {
    const auto& series = scan.series[s];
    const auto& g = series.geometry;
    const bool is_default = scan.default_series == s;
    out << (is_default ? "* " : "  ") << series.id << "  " << series.modality;
    if (options.show_descriptions && !series.description.empty()) {
      out << "  \"" << series.description << "\"";
    }
    out << "\n      ";
    if (series.role == dicom::SeriesRole::localizer) {
      out << "localizer, not a volume (" << series.role_reason << "), " << series.slices.size()
          << " image(s)\n";
      continue;
    }
    if (!g.ok()) {
      out << series.slices.size() << " slices, REFUSED: " << g.error << "\n";
      continue;
    }
    out << series.columns << "x" << series.rows << "x" << g.output_slices << " voxels, "
        << format("%.3f x %.3f x %.3f mm", g.index_to_patient.spacing(0),
                  g.index_to_patient.spacing(1), g.slice_step_mm)
        << ", " << orientation_label(series);
    if (g.tilt_degrees > 0.01) out << format(", gantry tilt %.2f deg", g.tilt_degrees, 0, 0);
    if (values[s].hu_range) {
      out << format(", values %.0f..%.0f HU", values[s].hu_range->first,
                    values[s].hu_range->second, 0);
    }
    out << "\n";
    if (!values[s].error.empty()) out << "      REFUSED: " << values[s].error << "\n";
    for (const auto& w : values[s].warnings) out << "      warning: " << w << "\n";
  }
  for (const auto& w : scan.warnings) out << "warning: " << w << "\n";
  if (scan.default_series) {
    out << "default series: " << scan.series[*scan.default_series].id << "\n";
  } else {
    out << "no usable CT series\n";
  }
  if (scan.skipped.empty()) return;
  // Grouped by reason: a study folder can hold thousands of skipped files of a few kinds.
  std::map<std::string, std::vector<const dicom::SkippedFile*>> by_reason;
  for (const auto& file : scan.skipped) {
    by_reason[std::string(dicom::to_string(file.kind)) + ": " + file.reason].push_back(&file);
  }
  out << "skipped files:\n";
  for (const auto& [reason, files] : by_reason) {
    out << "  " << files.size() << " x " << reason;
    if (!options.list_skipped) {
      out << " (e.g. " << files.front()->path.string() << ")\n";
      continue;
    }
    out << "\n";
    for (const auto* file : files) out << "      " << file->path.string() << "\n";
  }
}

}  // namespace

void add_info_command(CLI::App& app, InfoOptions& options) {
  CLI::App* command = app.add_subcommand(
      "info", "List the series in a DICOM folder, the files skipped and why, and the default");
  add_input_options(*command, options.input);
  command->add_flag("--json", options.json, "Machine-readable output on stdout");
  command->add_flag("--list-skipped", options.list_skipped, "List every skipped file");
  command->add_flag("--show-descriptions", options.show_descriptions,
                    "Show each series' SeriesDescription (free text that can identify the "
                    "patient; hidden by default)");
}

int run_info(const InfoOptions& options, std::ostream& out) {
  if (const InputKind kind = input_kind(options.input.input); kind != InputKind::dicom) {
    return run_volume_file_info(options, kind, out);
  }
  const dicom::FolderScan scan = scan_input(options.input);
  std::vector<SeriesValues> values;
  for (const auto& series : scan.series) values.push_back(load_values(series));

  if (options.json) {
    json document = {{"files_seen", scan.files_seen}, {"series", json::array()},
                     {"skipped", json::array()}, {"warnings", scan.warnings}};
    for (std::size_t s = 0; s < scan.series.size(); ++s) {
      document["series"].push_back(series_json(scan.series[s], values[s], scan.default_series == s,
                                                 options.show_descriptions));
    }
    for (const auto& file : scan.skipped) {
      document["skipped"].push_back(
          {{"path", file.path.string()}, {"kind", dicom::to_string(file.kind)}, {"reason", file.reason}});
    }
    document["default_series"] =
        scan.default_series ? json(scan.series[*scan.default_series].id) : json(nullptr);
    out << document.dump(2) << "\n";
  } else {
    print_text(scan, values, options, out);
  }
  return scan.default_series ? kExitOk : kExitInputRefused;
}

}  // namespace typemerge::app
