#include "app/stats_command.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <ostream>

#include "app/exit_codes.h"
#include "core/mesh_checks.h"
#include "core/self_intersections.h"
#include "io/stl_writer.h"

namespace typemerge::app {

void add_stats_command(CLI::App& app, StatsOptions& options) {
  CLI::App* command = app.add_subcommand(
      "stats", "Triangles, vertices, defects, components, Euler characteristic, volume, area");
  command->add_option("MESH", options.mesh, "STL file (binary or ASCII)")->required();
  command->add_flag("--json", options.json, "Machine-readable output");
  command->add_flag("--self-intersections", options.self_intersections,
                    "Also count pairs of triangles that cross or overlap (exact predicates; "
                    "a printable solid has none)");
}

int run_stats(const StatsOptions& options, std::ostream& out) {
  core::TriangleMesh mesh;
  try {
    mesh = io::read_stl(options.mesh);
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  const core::MeshCheck check = core::check_mesh(mesh);
  nlohmann::ordered_json document = {
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
  if (options.self_intersections) {
    const core::SelfIntersections crossings = core::find_self_intersections(mesh);
    document["self_intersecting_pairs"] = crossings.pairs.size();
    // Where to look: the centroids of the first few pairs' first triangles, in file units.
    nlohmann::ordered_json where = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < std::min<std::size_t>(crossings.pairs.size(), 5); ++i) {
      const auto& t = mesh.triangles[crossings.pairs[i][0]];
      std::array<double, 3> centroid{};
      for (std::uint32_t v : t) {
        for (int k = 0; k < 3; ++k) centroid[k] += mesh.positions[v][k] / 3.0;
      }
      where.push_back(centroid);
    }
    document["self_intersections_at"] = where;
  }
  if (options.json) {
    out << document.dump(2) << "\n";
  } else {
    for (const auto& [key, value] : document.items()) out << key << ": " << value.dump() << "\n";
  }
  return kExitOk;
}

}  // namespace typemerge::app
