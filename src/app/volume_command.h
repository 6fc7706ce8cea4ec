// `typemerge volume DIR [--series ID] -o vol.nrrd`: the exact HU volume that would be meshed.
#pragma once

#include <iosfwd>
#include <string>

#include "app/input_options.h"

namespace typemerge::app {

struct VolumeOptions {
  InputOptions input;
  std::string series_id;
  std::string output;
  bool float_samples = false;
};

void add_volume_command(CLI::App& app, VolumeOptions& options);
int run_volume(const VolumeOptions& options, std::ostream& log);

}  // namespace typemerge::app
