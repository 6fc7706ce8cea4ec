// `typemerge stats mesh.stl [--json] [--self-intersections]`: the numbers that say whether a
// mesh is printable.
#pragma once

#include <iosfwd>
#include <string>

namespace CLI {
class App;
}

namespace typemerge::app {

struct StatsOptions {
  std::string mesh;
  bool json = false;
  bool self_intersections = false;  // also count crossing triangle pairs (exact, CGAL)
};

void add_stats_command(CLI::App& app, StatsOptions& options);
int run_stats(const StatsOptions& options, std::ostream& out);

}  // namespace typemerge::app
