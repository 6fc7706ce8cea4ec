// Time of every mesh step beside what it did, on a large noisy blob (the size of a CT skin
// surface). Not a test and never gates.
//   mesh_bench [n = 300] [noise = 0.5] [decimation target fraction = 0.1] [max_error = 0.2]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "core/marching_cubes.h"
#include "core/test_volumes.h"
#include "mesh/components.h"
#include "mesh/decimation.h"
#include "mesh/smoothing.h"
#include "mesh/validity.h"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace typemerge;
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

  mesh::DecimationOptions options;
  options.target_triangles = static_cast<std::size_t>(fraction * static_cast<double>(mesh.triangles.size()));
  options.max_error = max_error;
  start = Clock::now();
  const mesh::DecimationReport decimation = mesh::decimate_mesh(mesh, options);
  std::printf("decimate_mesh (target %zu, max_error %.3f): %zu → %zu triangles, reached %d, "
              "valid %d, χ %lld, volume %.0f, %.2f s\n",
              options.target_triangles, decimation.max_error, decimation.triangles_before,
              decimation.triangles_after, decimation.reached_target, decimation.validity.valid(),
              static_cast<long long>(decimation.validity.check.euler_characteristic),
              decimation.validity.check.volume, seconds_since(start));
  return 0;
}
