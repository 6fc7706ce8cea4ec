// Throughput of extract_isosurface on a sphere (one thread), printed beside the mesh it made.
// Usage: core_bench [n = 256] [repetitions = 5]; reports the median. Not a test: never gates.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "test_volumes.h"

int main(int argc, char** argv) {
  using namespace typemerge::core;
  const std::int64_t n = argc > 1 ? std::atoll(argv[1]) : 256;
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 5;
  const double centre = 0.5 * static_cast<double>(n - 1) + 0.13;
  const Volume volume =
      test::sphere_volume(n, 0.4 * static_cast<double>(n), centre, centre - 0.21, centre + 0.07);

  for (auto mode : {ExtractOptions::Mode::consistent, ExtractOptions::Mode::classic}) {
    ExtractOptions options;
    options.mode = mode;
    std::vector<double> seconds;
    TriangleMesh mesh;
    for (int r = 0; r < repetitions; ++r) {
      const auto start = std::chrono::steady_clock::now();
      mesh = extract_isosurface(volume, 0.0f, options);
      seconds.push_back(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    std::sort(seconds.begin(), seconds.end());
    const double median = seconds[seconds.size() / 2];
    const double cells =
        static_cast<double>(n + 1) * static_cast<double>(n + 1) * static_cast<double>(n + 1);
    const MeshCheck check = check_mesh(mesh);
    std::printf(
        "%s sphere %lld^3: %.1f ms median of %d, %.1f M cells/s (padded cells), "
        "%zu triangles, %zu vertices, closed manifold %s, chi %lld\n",
        mode == ExtractOptions::Mode::consistent ? "consistent" : "classic   ",
        static_cast<long long>(n), median * 1e3, repetitions, cells / median * 1e-6,
        mesh.triangles.size(), mesh.positions.size(), check.closed_manifold() ? "yes" : "no",
        static_cast<long long>(check.euler_characteristic));
  }
}
