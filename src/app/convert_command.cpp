#include "app/convert_command.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <ostream>

#include "app/exit_codes.h"
#include "app/version.h"
#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "io/stl_writer.h"

namespace typemerge::app {

void add_convert_command(CLI::App& app, ConvertOptions& options) {
  CLI::App* command = app.add_subcommand("convert", "Extract an isosurface as binary STL (LPS mm)");
  add_input_options(*command, options.input);
  command->add_option("--series", options.series_id, "Series id from `typemerge info`");
  command->add_option("--iso", options.iso, "Iso value in HU (inside: value >= iso)")->required();
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
  core::TriangleMesh mesh = core::extract_isosurface(loaded.volume, static_cast<float>(options.iso),
                                                     extract);
  core::to_patient(mesh, loaded.volume.geometry());
  const auto extracted_at = Clock::now();
  if (mesh.empty()) {
    throw CommandError{kExitInputRefused, "no surface at " + std::to_string(options.iso) +
                                              " HU: values range from " +
                                              std::to_string(loaded.min_hu) + " to " +
                                              std::to_string(loaded.max_hu)};
  }
  try {
    io::write_binary_stl(mesh, options.output, io::stl_header(kVersion, "LPS"));
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
