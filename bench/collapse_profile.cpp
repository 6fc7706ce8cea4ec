// collapse_profile: the bounded collapses alone (bounded_collapse.h), for profiling. Extracts
// once, as --reduce-to's second stage starts (type merging at half the cap, marching cubes'
// surface as the reference, both in patient mm), then times only collapse_within_bound to each
// target, on one thread, and prints its counters.
//
//   collapse_profile (--series DIR | --synthetic NXxNYxNZ) [--iso 300] [--targets 0.25,0.1]
//                    [--bound-steps 2.5] [--local-share 0] [--place 0] [--repeat 1]
//                    [--ladder S1,S2,...]
//
// --targets: shares of marching cubes' triangles; --bound-steps: the bound in finest voxel
// steps (2.5 = half of kReductionCapSteps, where --reduce-to collapses first); --local-share:
// CollapseOptions::local_rms as a share of the bound (0: none; --max-error uses
// kLocalErrorShare), with targets of 0 to collapse as far as that allows; --place 1: with
// placement (CollapseOptions::move_vertices, in patient mm). Each run also prints the maximum
// and mean distance to marching cubes' surface (both surfaces sampled every 0.5 mm). --ladder:
// after the collapses within --bound-steps stop short of a target, collapses go on from where
// they stopped within each larger bound of the list (finest voxel steps) in turn, each rung's
// count and CPU printed. Run under
// `perf record -g` or `valgrind --tool=callgrind` to see where the collapse time goes.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

#include <time.h>

#include "core/bounded_collapse.h"
#include "core/bounded_reduction.h"
#include "core/marching_cubes.h"
#include "core/mesh_distance.h"
#include "core/type_merging.h"
#include "default_series.h"
#include "list_argument.h"
#include "synthetic_volume.h"

namespace {

using namespace typemerge;
using Clock = std::chrono::steady_clock;

// This thread's CPU time in ms: on a shared host, steadier than the wall clock.
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

int usage() {
  std::fprintf(stderr,
               "usage: collapse_profile (--series DIR | --synthetic NXxNYxNZ) [--iso 300]\n"
               "         [--targets 0.25,0.1] [--bound-steps 2.5] [--local-share 0] [--place 0]\n"
               "         [--repeat 1] [--ladder S1,S2,...]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::string series_dir, synthetic, iso_list = "300", targets = "0.25,0.1", ladder;
  double bound_steps = 0.5 * core::kReductionCapSteps;
  double local_share = 0.0;
  bool place = false;
  int repeat = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--series") series_dir = value;
    else if (key == "--synthetic") synthetic = value;
    else if (key == "--iso") iso_list = value;
    else if (key == "--targets") targets = value;
    else if (key == "--bound-steps") bound_steps = std::stod(value);
    else if (key == "--local-share") local_share = std::stod(value);
    else if (key == "--place") place = value != "0";
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--ladder") ladder = value;
    else return usage();
  }
  if (series_dir.empty() == synthetic.empty()) return usage();
  core::Volume volume;
  if (!synthetic.empty()) {
    long nx = 0, ny = 0, nz = 0;
    if (std::sscanf(synthetic.c_str(), "%ldx%ldx%ld", &nx, &ny, &nz) != 3) return usage();
    volume = bench::synthetic_volume(nx, ny, nz);
  } else {
    auto loaded = bench::load_default_series(series_dir, false);
    if (!loaded) return 1;
    volume = std::move(*loaded);
  }
  const core::IndexToPatient& g = volume.geometry();
  const double bound = bound_steps * std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
  core::ExtractOptions extract;
  extract.threads = 1;
  extract.vertex_normals = false;
  for (const std::string& iso_text : bench::split(iso_list)) {
    const float iso = std::stof(iso_text);
    core::TriangleMesh reference = core::extract_isosurface(volume, iso, extract);
    core::to_patient(reference, g);
    core::MergeOptions options;
    options.epsilon_mm = bound;
    core::TriangleMesh merged = core::extract_type_merged(volume, iso, extract, options);
    core::to_patient(merged, g);
    std::printf("iso %g: mc %zu triangles, merged within %.3f mm %zu\n", double(iso),
                reference.triangles.size(), bound, merged.triangles.size());
    for (const std::string& share : bench::split(targets)) {
      const auto n = static_cast<std::size_t>(std::stod(share) * double(reference.triangles.size()));
      for (int r = 0; r < repeat; ++r) {
        core::TriangleMesh work = merged;
        const auto start = Clock::now();
        const double cpu_start = cpu_ms();
        core::CollapseOptions collapse{bound, n, local_share * bound};
        collapse.move_vertices = place;
        core::CollapseStats s = core::collapse_within_bound(work, reference, collapse);
        double rung_bound = bound;
        for (const std::string& rung : bench::split(ladder)) {
          if (work.triangles.size() <= n) break;
          std::printf("  within %.3f mm: %zu triangles after %.1f ms CPU\n", rung_bound,
                      work.triangles.size(), cpu_ms() - cpu_start);
          rung_bound = std::stod(rung) * std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
          collapse.bound = rung_bound;
          collapse.local_rms = local_share * rung_bound;
          const core::CollapseStats more = core::collapse_within_bound(work, reference, collapse);
          s.collapses += more.collapses;
          s.refused_topology += more.refused_topology;
          s.refused_shape += more.refused_shape;
          s.refused_distance += more.refused_distance;
          s.refused_crossing += more.refused_crossing;
          s.overlay_proofs += more.overlay_proofs;
          s.reference_overlay_proofs += more.reference_overlay_proofs;
          s.held_reference_triangles = more.held_reference_triangles;  // the last rung's
        }
        if (!ladder.empty()) std::printf("  last bound %.3f mm\n", rung_bound);
        const double cpu = cpu_ms() - cpu_start;
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        core::remove_unreferenced_vertices(work);
        const core::SymmetricMeshDistance d = core::surface_distance(reference, work, 0.5, 1);
        std::printf("  target %zu (%s): %.1f ms (CPU %.1f ms), %zu triangles; %zu collapses; "
                    "refused %zu topology, %zu shape, %zu distance, %zu crossing; %zu held; "
                    "%zu passed over; %zu + %zu overlay proofs; distance max %.3f mean %.4f mm\n",
                    n, share.c_str(), ms, cpu, work.triangles.size(), s.collapses, s.refused_topology,
                    s.refused_shape, s.refused_distance, s.refused_crossing,
                    s.held_reference_triangles, s.passed_over_local_error, s.overlay_proofs,
                    s.reference_overlay_proofs,
                    d.hausdorff(), d.mean());
      }
    }
  }
  return 0;
}
