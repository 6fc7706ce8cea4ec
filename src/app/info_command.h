// `typemerge info DIR [--json]`: what a folder holds and what would be meshed.
#pragma once

#include <iosfwd>

#include "app/input_options.h"

namespace typemerge::app {

struct InfoOptions {
  InputOptions input;
  bool json = false;
  bool list_skipped = false;
  // SeriesDescription is free text (it can hold a name): shown only when asked for.
  bool show_descriptions = false;
};

void add_info_command(CLI::App& app, InfoOptions& options);
int run_info(const InfoOptions& options, std::ostream& out);

}  // namespace typemerge::app
