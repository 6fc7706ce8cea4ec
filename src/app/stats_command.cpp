#include "app/stats_command.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <ostream>

#include "app/exit_codes.h"
#include "core/mesh_checks.h"
#include "io/stl_writer.h"

namespace typemerge::app {

void add_stats_command(CLI::App& app, StatsOptions& options) {
  CLI::App* command = app.add_subcommand(
      "stats", "Triangles, vertices, defects, components, Euler characteristic, volume, area");
  command->add_option("MESH", options.mesh, "STL file (binary or ASCII)")->required();
  command->add_flag("--json", options.json, "Machine-readable output");
}

int run_stats(const StatsOptions& options, std::ostream& out) {
  core::TriangleMesh mesh;
  try {
    mesh = io::read_stl(options.mesh);
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  const core::MeshCheck check = core::check_mesh(mesh);
  const nlohmann::ordered_json document = {
      {"triangles", check.triangles},
      {"vertices", check.vertices},
      {"edges", check.edges},
      {"boundary_edges", check.boundary_edges},
      {"non_manifold_edges", check.non_manifold_edges},
      {"inconsistent_edges", check.inconsistent_edges},
      {"non_manifold_vertices", check.non_manifold_vertices},
      {"degenerate_triangles", check.degenerate_triangles},
      {"components", check.components},
      {"euler_characteristic", check.euler_characteristic},
      {"volume_mm3", check.volume},
      {"area_mm2", check.area},
      {"closed_manifold", check.closed_manifold()},
  };
  if (options.json) {
    out << document.dump(2) << "\n";
  } else {
    for (const auto& [key, value] : document.items()) out << key << ": " << value.dump() << "\n";
  }
  return kExitOk;
}

}  // namespace typemerge::app
