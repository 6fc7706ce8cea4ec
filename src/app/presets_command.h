// `typemerge presets`: the tissue presets and their HU windows.
#pragma once

#include <iosfwd>

namespace CLI {
class App;
}

namespace typemerge::app {

void add_presets_command(CLI::App& app);
int run_presets(std::ostream& out);

}  // namespace typemerge::app
