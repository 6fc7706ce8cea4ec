// `typemerge convert DIR (--preset NAME | --iso HU | --window LO,HI) -o out.stl`: one surface.
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "app/input_options.h"

namespace typemerge::app {

struct ConvertOptions {
  InputOptions input;
  std::string series_id;
  std::string output;
  std::optional<double> iso;
  std::string preset;
  std::vector<double> window;  // lo, hi
  std::string algorithm = "mc";
  bool open_borders = false;
  std::string preview;
};

void add_convert_command(CLI::App& app, ConvertOptions& options);
int run_convert(const ConvertOptions& options, std::ostream& log);

}  // namespace typemerge::app
