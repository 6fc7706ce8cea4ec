// Throughput of extract_isosurface + merge_types on a sphere (one thread), printed beside the
// mesh quality it gives. Usage: type_merging_bench [n = 256] [repetitions = 5] [run_cap = 6];
// reports medians. Not a test: never gates.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/type_merging.h"
#include "test_volumes.h"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  using namespace typemerge::core;
  using Clock = std::chrono::steady_clock;
  const std::int64_t n = argc > 1 ? std::atoll(argv[1]) : 256;
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 5;
  MergeOptions options;
  if (argc > 3) options.run_cap = std::atoi(argv[3]);
  const double centre = 0.5 * static_cast<double>(n - 1) + 0.13;
  const Volume volume =
      test::sphere_volume(n, 0.4 * static_cast<double>(n), centre, centre - 0.21, centre + 0.07);

  std::vector<double> extract_seconds;
  std::vector<double> merge_seconds;
  TriangleMesh mc;
  TriangleMesh tm;
  MergeStats stats;
  for (int r = 0; r < repetitions; ++r) {
    std::vector<BoundaryCube> cubes;
    ExtractOptions extract;
    extract.cubes = &cubes;
    const auto t0 = Clock::now();
    mc = extract_isosurface(volume, 0.0f, extract);
    const auto t1 = Clock::now();
    tm = mc;
    const auto t2 = Clock::now();
    merge_types(tm, cubes, options, &stats);
    const auto t3 = Clock::now();
    extract_seconds.push_back(std::chrono::duration<double>(t1 - t0).count());
    merge_seconds.push_back(std::chrono::duration<double>(t3 - t2).count());
  }
  const double cells =
      static_cast<double>(n + 1) * static_cast<double>(n + 1) * static_cast<double>(n + 1);
  const double te = median(extract_seconds);
  const double tmerge = median(merge_seconds);
  const MeshCheck mc_check = check_mesh(mc);
  const MeshCheck tm_check = check_mesh(tm);
  std::printf("sphere %lld^3, run cap %d, epsilon %.2f voxel, median of %d, one thread\n",
              static_cast<long long>(n), options.run_cap, options.epsilon_voxels, repetitions);
  std::printf("  extract (MC + cube records): %8.1f ms  %7.1f M cells/s (padded cells)\n",
              te * 1e3, cells / te * 1e-6);
  std::printf("  merge:                       %8.1f ms  %7.1f M cells/s\n", tmerge * 1e3,
              cells / tmerge * 1e-6);
  std::printf("  extract + merge:             %8.1f ms  %7.1f M cells/s\n", (te + tmerge) * 1e3,
              cells / (te + tmerge) * 1e-6);
  std::printf("  triangles %zu -> %zu (%.1f %%), vertices %zu -> %zu\n", mc.triangles.size(),
              tm.triangles.size(),
              100.0 * static_cast<double>(tm.triangles.size()) /
                  static_cast<double>(mc.triangles.size()),
              mc.positions.size(), tm.positions.size());
  std::printf("  MC: closed manifold %s, chi %lld | TM: closed manifold %s, chi %lld, components %zu\n",
              mc_check.closed_manifold() ? "yes" : "no",
              static_cast<long long>(mc_check.euler_characteristic),
              tm_check.closed_manifold() ? "yes" : "no",
              static_cast<long long>(tm_check.euler_characteristic), tm_check.components);
  std::printf("  volume ratio TM/MC %.6f, area ratio %.6f\n", tm_check.volume / mc_check.volume,
              tm_check.area / mc_check.area);
  std::printf(
      "  merges by type %zu/%zu/%zu (hexagon %zu, minor %zu), capped %zu, abandoned %zu\n"
      "  collapses %zu of %zu tried; rejected: boundary %zu link %zu fan %zu normal %zu "
      "gradient %zu distance %zu; slivers removed %zu, left %zu\n",
      stats.cubes_merged_by_type[0], stats.cubes_merged_by_type[1], stats.cubes_merged_by_type[2],
      stats.hexagon_merges, stats.minor_merges, stats.runs_capped, stats.merges_abandoned,
      stats.collapses_done, stats.collapses_tried, stats.rejected_boundary, stats.rejected_link,
      stats.rejected_fan_size, stats.rejected_normal, stats.rejected_gradient,
      stats.rejected_distance, stats.sliver_collapses, stats.slivers_left);
}
