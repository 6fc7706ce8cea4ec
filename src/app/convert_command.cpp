#include "app/convert_command.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>

#include "app/exit_codes.h"
#include "app/version.h"
#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/window_field.h"
#include "io/preview_png.h"
#include "app/presets.h"
#include "dicom/series_loader.h"
#include "io/stl_writer.h"

namespace typemerge::app {

namespace {

// What to extract: value >= lo, or lo <= value <= hi.
struct SurfaceRequest {
  double lo = 0;
  std::optional<double> hi;
  std::string label;
  bool from_preset = false;
};

SurfaceRequest surface_request(const ConvertOptions& options) {
  SurfaceRequest request;
  if (!options.preset.empty()) {
    const auto preset = find_preset(options.preset);
    if (!preset) {
      throw CommandError{kExitUsage, "unknown preset '" + options.preset +
                                         "' (see `typemerge presets`)"};
    }
    request = {preset->lo, std::nullopt, "preset " + preset->name, true};
    if (std::isfinite(preset->hi)) request.hi = preset->hi;
  } else if (options.iso) {
    char label[64];
    std::snprintf(label, sizeof label, "iso %g HU", *options.iso);
    request = {*options.iso, std::nullopt, label, false};
  } else if (options.window.size() == 2) {
    if (!(options.window[0] <= options.window[1])) {
      throw CommandError{kExitUsage, "--window LO,HI needs LO <= HI"};
    }
    request = {options.window[0], options.window[1], "window", false};
  } else {
    throw CommandError{kExitUsage, "say what to extract: --preset NAME, --iso HU or --window LO,HI"};
  }
  return request;
}

// A preset assumes Hounsfield units and a tissue that is there: check both rather than write
// an empty mesh or a box (everything inside).
void check_tissue(const dicom::LoadedSeries& loaded, const SurfaceRequest& request) {
  if (request.from_preset &&
      !dicom::hounsfield_plausibility_warning(loaded.min_hu, loaded.max_hu).empty()) {
    throw CommandError{kExitInputRefused,
                       "the values of this series do not look like Hounsfield units (" +
                           std::to_string(loaded.min_hu) + " to " + std::to_string(loaded.max_hu) +
                           "), so " + request.label + " would not fit; give --iso or --window "
                           "in this data's units"};
  }
  const float hi = request.hi ? static_cast<float>(*request.hi)
                              : std::numeric_limits<float>::infinity();
  const auto inside = core::count_in_window(loaded.volume, static_cast<float>(request.lo), hi);
  const auto total = loaded.volume.size().voxels();
  if (inside == 0) {
    throw CommandError{kExitInputRefused, "no surface: no voxel inside " + request.label +
                                              ", the tissue is absent from this series"};
  }
  if (inside == total) {
    throw CommandError{kExitInputRefused, "every voxel is inside " + request.label +
                                              ": the surface would be the volume's box"};
  }
}

}  // namespace

void add_convert_command(CLI::App& app, ConvertOptions& options) {
  CLI::App* command = app.add_subcommand("convert", "Extract an isosurface as binary STL (LPS mm)");
  add_input_options(*command, options.input);
  command->add_option("--series", options.series_id, "Series id from `typemerge info`");
  auto* preset = command->add_option("--preset", options.preset,
                                     "Tissue preset (see `typemerge presets`)");
  auto* iso = command->add_option("--iso", options.iso, "Iso value in HU (inside: value >= iso)");
  auto* window = command->add_option("--window", options.window,
                                     "HU window LO,HI: the surface around voxels inside it")
                     ->delimiter(',')
                     ->expected(2);
  preset->excludes(iso)->excludes(window);
  iso->excludes(window);
  command->add_option("--preview", options.preview, "Also write a shaded PNG preview");
  command->add_option("-o,--output", options.output, "Output .stl file")->required();
  command->add_option("--algorithm", options.algorithm,
                      "mc: topologically consistent marching cubes; classic: fixed-table "
                      "marching cubes (shows the holes of ambiguous cubes)")
      ->check(CLI::IsMember({"mc", "classic"}));
  command->add_flag("--open-borders", options.open_borders,
                    "Leave surfaces open where they meet the volume border (default: closed)");
}

int run_convert(const ConvertOptions& options, std::ostream& log) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  dicom::FolderScan scan;
  try {
    scan = dicom::scan_folder(options.input.input, options.input.scan_options());
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  const dicom::SeriesInfo& series = select_series(scan, options.series_id);
  dicom::LoadedSeries loaded;
  try {
    loaded = dicom::load_series(series);
  } catch (const dicom::LoadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  for (const auto& w : loaded.warnings) log << "warning: " << w << "\n";
  const auto loaded_at = Clock::now();

  core::ExtractOptions extract;
  extract.close_borders = !options.open_borders;
  extract.mode = options.algorithm == "classic" ? core::ExtractOptions::Mode::classic
                                                : core::ExtractOptions::Mode::consistent;
  const SurfaceRequest request = surface_request(options);
  check_tissue(loaded, request);
  core::TriangleMesh mesh;
  if (request.hi) {
    mesh = core::extract_isosurface(
        core::window_field(loaded.volume, static_cast<float>(request.lo),
                           static_cast<float>(*request.hi)),
        0.0f, extract);
  } else {
    mesh = core::extract_isosurface(loaded.volume, static_cast<float>(request.lo), extract);
  }
  core::to_patient(mesh, loaded.volume.geometry());
  const auto extracted_at = Clock::now();
  if (mesh.empty()) {
    throw CommandError{kExitInputRefused, "no surface for " + request.label +
                                              ": values range from " +
                                              std::to_string(loaded.min_hu) + " to " +
                                              std::to_string(loaded.max_hu)};
  }
  try {
    io::write_binary_stl(mesh, options.output, io::stl_header(kVersion, "LPS"));
    if (!options.preview.empty()) io::write_preview_png(mesh, options.preview);
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitOutputFailed, error.what()};
  }
  const auto written_at = Clock::now();
  auto ms = [](auto a, auto b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  };
  char text[256];
  std::snprintf(text, sizeof text,
                "series %s: %zu triangles, %zu vertices written to %s (load %.0f ms, extract "
                "%.0f ms, write %.0f ms)\n",
                series.id.c_str(), mesh.triangles.size(), mesh.positions.size(),
                options.output.c_str(), ms(start, loaded_at), ms(loaded_at, extracted_at),
                ms(extracted_at, written_at));
  log << text;
  return kExitOk;
}

}  // namespace typemerge::app
