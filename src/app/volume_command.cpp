#include "app/volume_command.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <ostream>

#include "app/exit_codes.h"
#include "io/nrrd_writer.h"

namespace typemerge::app {

void add_volume_command(CLI::App& app, VolumeOptions& options) {
  CLI::App* command = app.add_subcommand(
      "volume", "Write the Hounsfield volume of a series as NRRD (LPS), as it would be meshed");
  add_input_options(*command, options.input);
  command->add_option("--series", options.series_id, "Series id from `typemerge info`");
  command->add_option("-o,--output", options.output, "Output .nrrd file")->required();
  command->add_flag("--float", options.float_samples,
                    "Write float samples (default: int16, rounded to whole HU)");
}

int run_volume(const VolumeOptions& options, std::ostream& log) {
  LoadedInput input = load_input(options.input, options.series_id);
  const dicom::SeriesInfo& series = *input.series;
  dicom::LoadedSeries& loaded = input.loaded;
  // int16 would silently round a fractional rescale; say so rather than lose it unnoticed.
  bool fractional = false;
  // int16 samples are whole HU by construction.
  if (!loaded.volume.holds_int16()) {
    for (float v : loaded.volume.samples()) {
      if (v != std::nearbyint(v)) {
        fractional = true;
        break;
      }
    }
  }
  if (fractional && !options.float_samples) {
    loaded.warnings.emplace_back("values have fractions of a HU; int16 output rounds them "
                                 "(use --float to keep them)");
  }
  try {
    io::write_nrrd(loaded.volume, options.output,
                   options.float_samples ? io::NrrdSampleType::float32 : io::NrrdSampleType::int16);
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitOutputFailed, error.what()};
  }
  const auto& size = loaded.volume.size();
  log << "series " << series.id << ": " << size.nx << "x" << size.ny << "x" << size.nz
      << " voxels written to " << options.output << "\n";
  for (const auto& w : loaded.warnings) log << "warning: " << w << "\n";
  return kExitOk;
}

}  // namespace typemerge::app
