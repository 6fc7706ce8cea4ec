// Time of every mesh step beside what it did, on a large noisy blob (the size of a CT skin
// surface). Not a test and never gates.
//   mesh_bench [n = 300] [noise = 0.5] [decimation target fraction = 0.1] [max_error = 0.2]
//
// OpenMesh's bounded decimation (mesh/decimation.h, the benchmarks' baseline) on a surface
// written by `typemerge convert` (e.g. abdomen bone, --algorithm mc, about 900 k triangles):
//   mesh_bench --stl FILE [--reduce-to N] [--max-error MM] [--spacing MM = 0.5]
//              [--threads T = 0]
// --reduce-to alone decimates blindly to N triangles (max_error infinite); --max-error alone as
// far as that bound allows; both: to N within the bound. Prints wall time, triangles, the
// symmetric Hausdorff and mean distance to the input sampled over both surfaces
// (core::surface_distance at --spacing, on --threads), closed manifold, χ, components and
// crossing pairs.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "core/marching_cubes.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/test_volumes.h"
#include "io/stl_writer.h"
#include "mesh/components.h"
#include "mesh/decimation.h"
#include "mesh/smoothing.h"
#include "mesh/validity.h"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// mesh_bench --stl FILE ...: see the top of this file.
int decimate_stl(int argc, char** argv) {
  using namespace typemerge;
  std::string stl;
  std::size_t target = 0;
  double max_error = std::numeric_limits<double>::infinity();
  double spacing = 0.5;
  unsigned threads = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const char* value = argv[i + 1];
    if (flag == "--stl") {
      stl = value;
    } else if (flag == "--reduce-to") {
      target = static_cast<std::size_t>(std::atoll(value));
    } else if (flag == "--max-error") {
      max_error = std::atof(value);
    } else if (flag == "--spacing") {
      spacing = std::atof(value);
    } else if (flag == "--threads") {
      threads = static_cast<unsigned>(std::atoi(value));
    } else {
      std::fprintf(stderr, "unknown option %s\n", argv[i]);
      return 2;
    }
  }
  if (stl.empty() || (target == 0 && !std::isfinite(max_error))) {
    std::fprintf(stderr, "mesh_bench --stl FILE needs --reduce-to N and/or --max-error MM\n");
    return 2;
  }
  const core::TriangleMesh input = io::read_stl(stl);
  const mesh::Validity before = mesh::check_validity(input);
  std::printf("%s: %zu triangles, closed manifold %d, χ %lld, %zu components; target %zu, "
              "max_error %g mm, distances sampled at %g mm\n",
              stl.c_str(), input.triangles.size(), before.valid(),
              static_cast<long long>(before.check.euler_characteristic), before.check.components,
              target, max_error, spacing);
  core::TriangleMesh mesh = input;
  mesh::DecimationOptions options;
  options.target_triangles = target;
  options.max_error = max_error;
  const auto start = Clock::now();
  const mesh::DecimationReport report = mesh::decimate_mesh(mesh, options);
  const double seconds = seconds_since(start);
  const core::SymmetricMeshDistance distance =
      core::surface_distance(input, mesh, spacing, threads);
  const std::size_t crossings = core::find_self_intersections(mesh).pairs.size();
  std::printf("openmesh %zu → %zu triangles in %.2f s; Hausdorff %.3f mm (input→result %.3f, "
              "result→input %.3f), mean %.4f mm; closed manifold %d, χ %lld, %zu components, "
              "%zu crossing pairs\n",
              report.triangles_before, report.triangles_after, seconds, distance.hausdorff(),
              distance.a_to_b.max, distance.b_to_a.max, distance.mean(), report.validity.valid(),
              static_cast<long long>(report.validity.check.euler_characteristic),
              report.validity.check.components, crossings);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace typemerge;
  if (argc > 1 && std::strcmp(argv[1], "--stl") == 0) return decimate_stl(argc, argv);
  const std::int64_t n = argc > 1 ? std::atoll(argv[1]) : 300;
  const double noise = argc > 2 ? std::atof(argv[2]) : 0.5;
  const double fraction = argc > 3 ? std::atof(argv[3]) : 0.1;
  const double max_error = argc > 4 ? std::atof(argv[4]) : 0.2;

  // A lumpy ball filling ~80% of the grid, with a cavity, plus voxel noise (specks).
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> uniform(-noise, noise);
  const double c = 0.5 * static_cast<double>(n - 1);
  const double radius = 0.4 * static_cast<double>(n);
  auto start = Clock::now();
  const core::Volume volume = core::test::sample_volume(n, n, n, [&](double x, double y, double z) {
    const double dx = x - c, dy = y - c, dz = z - c;
    const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double lumps = 0.08 * radius * std::sin(0.05 * x) * std::sin(0.07 * y) * std::cos(0.04 * z);
    const double outer = radius + lumps - r;
    const double cavity = r - 0.3 * radius;
    return std::min(outer, cavity) + uniform(rng);
  });
  std::printf("volume %lld³ sampled in %.2f s\n", static_cast<long long>(n), seconds_since(start));

  start = Clock::now();
  core::TriangleMesh mesh = core::extract_isosurface(volume, 0.0f);
  std::printf("extract_isosurface: %zu triangles, %zu vertices, %.2f s\n", mesh.triangles.size(),
              mesh.positions.size(), seconds_since(start));

  start = Clock::now();
  mesh::Validity validity = mesh::check_validity(mesh);
  std::printf("check_validity: valid %d, %zu components, χ %lld, volume %.0f, %.2f s\n",
              validity.valid(), validity.check.components,
              static_cast<long long>(validity.check.euler_characteristic), validity.check.volume,
              seconds_since(start));

  start = Clock::now();
  const mesh::RepairReport repair = mesh::repair_mesh(mesh);
  std::printf("repair_mesh: %zu collapses, %zu degenerate left, %.2f s\n",
              repair.collapsed_zero_length_edges, repair.remaining_degenerate_triangles,
              seconds_since(start));

  start = Clock::now();
  mesh::ComponentReport components = mesh::remove_small_components(mesh, 10.0);
  std::printf("remove_small_components(10 mm³): %zu → %zu components, %zu removed (%.1f mm³), %.2f s\n",
              components.components_before, components.components_after,
              components.removed_components, components.removed_volume, seconds_since(start));

  core::TriangleMesh largest = mesh;
  start = Clock::now();
  components = mesh::keep_largest_component(largest);
  std::printf("keep_largest_component: %zu → %zu components, %zu removed (%.1f mm³), %.2f s\n",
              components.components_before, components.components_after,
              components.removed_components, components.removed_volume, seconds_since(start));

  start = Clock::now();
  components = mesh::fill_cavities(mesh);
  std::printf("fill_cavities: %zu → %zu components, %zu removed (%.1f mm³), %.2f s\n",
              components.components_before, components.components_after,
              components.removed_components, components.removed_volume, seconds_since(start));

  start = Clock::now();
  const mesh::SmoothingReport smoothing = mesh::smooth_mesh(mesh);
  std::printf("smooth_mesh (Taubin, %d iterations): volume change %+.4f %%, valid %d, χ %lld, %.2f s\n",
              smoothing.iterations, 100.0 * smoothing.relative_volume_change,
              smoothing.validity.valid(),
              static_cast<long long>(smoothing.validity.check.euler_characteristic),
              seconds_since(start));

  core::TriangleMesh reduced = mesh;
  mesh::DecimationOptions options;
  options.target_triangles =
      static_cast<std::size_t>(fraction * static_cast<double>(mesh.triangles.size()));
  options.max_error = max_error;
  start = Clock::now();
  const mesh::DecimationReport decimation = mesh::decimate_mesh(reduced, options);
  std::printf("decimate_mesh (target %zu, max_error %.3f): %zu → %zu triangles, reached %d, "
              "valid %d, χ %lld, volume %.0f, %.2f s\n",
              options.target_triangles, decimation.max_error, decimation.triangles_before,
              decimation.triangles_after, decimation.reached_target, decimation.validity.valid(),
              static_cast<long long>(decimation.validity.check.euler_characteristic),
              decimation.validity.check.volume, seconds_since(start));
  return 0;
}
