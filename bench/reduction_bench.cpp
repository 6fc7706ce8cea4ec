// reduction_bench: what a reduction costs and keeps, in one run. Type merging at bounds in
// millimetres (--max-error) and at triangle targets (--reduce-to), against marching cubes'
// surface on the same grid.
//
//   reduction_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]
//                   [--epsilons 0.5,1,2] [--blocks 8,16,32] [--targets 25%,10%]
//                   [--spacing resample] [--threads 1]
//
// Prints, per iso × bound × block size: one-thread extraction time, triangles and their share
// of marching cubes', the two-sided Hausdorff and mean distances to marching cubes' surface in
// mm (sampled at every vertex and over both surfaces, ≥ 1 point per mm²), crossing triangle
// pairs (exact), whether the surface is closed and manifold with marching cubes' Euler
// characteristic and components, and caps (> 170°) and needles (< 1°) beside marching cubes'.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/type_merging.h"
#include "default_series.h"
#include "list_argument.h"
#include "synthetic_volume.h"

namespace {

using namespace typemerge;
using Clock = std::chrono::steady_clock;

struct Quality {
  std::size_t triangles = 0;
  double hausdorff = 0;
  double mean = 0;
  std::size_t crossings = 0;
  bool valid = false;
  core::ExtremeAngles extremes;
};

// `mesh` in patient mm against `mc` (also in mm).
Quality measure(const core::TriangleMesh& mesh, const core::TriangleMesh& mc,
                const core::MeshCheck& mc_check, unsigned threads) {
  Quality q;
  q.triangles = mesh.triangles.size();
  const auto d = core::surface_distance(mc, mesh, 0.7, threads);
  q.hausdorff = d.hausdorff();
  q.mean = d.mean();
  q.crossings = core::find_self_intersections(mesh, 1000).pairs.size();
  const core::MeshCheck check = core::check_mesh(mesh, threads);
  q.valid = check.closed_manifold() &&
            check.euler_characteristic == mc_check.euler_characteristic &&
            check.components == mc_check.components;
  q.extremes = core::count_extreme_angles(mesh);
  return q;
}

void print(const char* what, double ms, const Quality& q, std::size_t mc_triangles) {
  std::printf("  %-22s %9.1f ms %9zu tri %6.2f %%  Hausdorff %6.3f mm  mean %6.4f mm  "
              "crossings %zu  %s  caps %zu needles %zu\n",
              what, ms, q.triangles, 100.0 * double(q.triangles) / double(mc_triangles),
              q.hausdorff, q.mean, q.crossings, q.valid ? "closed, same topology" : "DEFECTS",
              q.extremes.above_170, q.extremes.below_1);
}

int usage() {
  std::fprintf(stderr,
               "usage: reduction_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]\n"
               "         [--epsilons 0.5,1,2] [--blocks 8,16,32] [--spacing resample]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string series_dir, synthetic, iso_list = "300,-500", epsilons = "0.5,1,2",
                                     blocks = "8,16,32", spacing;
  unsigned threads = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--series") series_dir = value;
    else if (key == "--synthetic") synthetic = value;
    else if (key == "--iso") iso_list = value;
    else if (key == "--epsilons") epsilons = value;
    else if (key == "--blocks") blocks = value;
    else if (key == "--spacing") spacing = value;
    else if (key == "--threads") threads = static_cast<unsigned>(std::stoul(value));
    else return usage();
  }
  if (series_dir.empty() == synthetic.empty()) return usage();
  core::Volume volume;
  if (!synthetic.empty()) {
    long nx = 0, ny = 0, nz = 0;
    if (std::sscanf(synthetic.c_str(), "%ldx%ldx%ld", &nx, &ny, &nz) != 3) return usage();
    volume = bench::synthetic_volume(nx, ny, nz);
  } else {
    auto loaded = bench::load_default_series(series_dir, spacing == "resample");
    if (!loaded) return 1;
    volume = std::move(*loaded);
  }
  const core::IndexToPatient& geometry = volume.geometry();
  std::printf("volume %lld x %lld x %lld, spacing %.3f x %.3f x %.3f mm\n",
              static_cast<long long>(volume.size().nx), static_cast<long long>(volume.size().ny),
              static_cast<long long>(volume.size().nz), geometry.spacing(0), geometry.spacing(1),
              geometry.spacing(2));
  core::ExtractOptions extract;
  extract.threads = 1;
  extract.vertex_normals = false;
  for (const std::string& iso_text : bench::split(iso_list)) {
    const float iso = std::stof(iso_text);
    auto start = Clock::now();
    core::TriangleMesh mc = core::extract_isosurface(volume, iso, extract);
    const double mc_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    core::to_patient(mc, geometry);
    const core::MeshCheck mc_check = core::check_mesh(mc, threads);
    std::printf("iso %g: mc %zu triangles in %.1f ms, caps %zu needles %zu\n", double(iso),
                mc.triangles.size(), mc_ms, core::count_extreme_angles(mc).above_170,
                core::count_extreme_angles(mc).below_1);
    {
      core::MergeOptions options;
      start = Clock::now();
      core::TriangleMesh tm = core::extract_type_merged(volume, iso, extract, options);
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      core::to_patient(tm, geometry);
      print("tm default (0.5 vox)", ms, measure(tm, mc, mc_check, threads), mc.triangles.size());
    }
    for (const std::string& epsilon_text : bench::split(epsilons)) {
      for (const std::string& block_text : bench::split(blocks)) {
        core::MergeOptions options;
        options.epsilon_mm = std::stod(epsilon_text);
        options.block_cubes = static_cast<unsigned>(std::stoul(block_text));
        start = Clock::now();
        core::TriangleMesh tm = core::extract_type_merged(volume, iso, extract, options);
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        core::to_patient(tm, geometry);
        const std::string what = "tm " + epsilon_text + " mm, B " + block_text;
        print(what.c_str(), ms, measure(tm, mc, mc_check, threads), mc.triangles.size());
      }
    }
  }
  return 0;
}
