// `typemerge convert DIR --iso HU -o out.stl [--algorithm tm|mc|classic]`: one surface.
#pragma once

#include <iosfwd>
#include <string>

#include "app/input_options.h"

namespace typemerge::app {

struct ConvertOptions {
  InputOptions input;
  std::string series_id;
  std::string output;
  double iso = 0;
  std::string algorithm = "mc";
  bool open_borders = false;
};

void add_convert_command(CLI::App& app, ConvertOptions& options);
int run_convert(const ConvertOptions& options, std::ostream& log);

}  // namespace typemerge::app
