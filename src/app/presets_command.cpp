#include "app/presets_command.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <string>
#include <ostream>

#include "app/exit_codes.h"
#include "app/presets.h"

namespace typemerge::app {

void add_presets_command(CLI::App& app) {
  app.add_subcommand("presets", "List the tissue presets, their HU windows and 3MF colours");
}

int run_presets(std::ostream& out) {
  char line[160];
  std::snprintf(line, sizeof line, "%-20s %7s %7s  %-7s  %s\n", "preset", "lo HU", "hi HU",
                "colour", "tissue");
  out << line;
  for (const Preset& preset : presets()) {
    const std::string hi = std::isfinite(preset.hi) ? std::to_string(long(preset.hi)) : "-";
    // The colour is the preset's object's in a 3MF package, as #RRGGBB.
    std::snprintf(line, sizeof line, "%-20s %7.0f %7s  #%02X%02X%02X  %s\n", preset.name.c_str(),
                  preset.lo, hi.c_str(), preset.srgb[0], preset.srgb[1], preset.srgb[2],
                  preset.description.c_str());
    out << line;
  }
  return kExitOk;
}

}  // namespace typemerge::app
