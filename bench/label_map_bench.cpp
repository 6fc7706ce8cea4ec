// label_map_bench [--threads N] [NX NY NZ LABELS]: label mode's cost against one whole-volume
// extraction.
//
// A synthetic label map (default 256 × 256 × 160, 0.8 × 0.8 × 1 mm): a body ellipsoid cut into
// LABELS (default 100) touching Voronoi cells around jittered seeds, background outside, as an
// organ segmentation looks. Timed, as `convert --labels all` does them (app/label_mode.h): the
// census (one pass), then every label's smoothed, clamped field on its padded box and its
// extraction with finishing (extract_label_surfaces), twice: labels one after another, each
// extraction on N threads (as label mode did before labels ran in parallel), and labels in
// parallel over N threads (default all cores); against make_surface on the whole map on N
// threads (the body's surface at 0.5: one extraction of the whole volume). Prints the times,
// the ratios, triangles, validity, and whether both runs' surfaces are equal byte for byte.
// Each time is the faster of two runs (the field, extraction and check sums: the last run's).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "app/label_census.h"
#include "app/label_mode.h"
#include "app/label_surfaces.h"
#include "app/surface_pipeline.h"

namespace {

using namespace typemerge;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

core::Volume label_map(std::int64_t nx, std::int64_t ny, std::int64_t nz, int labels) {
  core::IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0, 1.0}}};
  core::Volume map({nx, ny, nz}, geometry);
  std::uint64_t state = 12345;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) * (1.0 / 9007199254740992.0);
  };
  const double cx = double(nx) / 2, cy = double(ny) / 2, cz = double(nz) / 2;
  auto in_body = [&](double i, double j, double k) {
    const double x = (i - cx) / (0.45 * double(nx)), y = (j - cy) / (0.35 * double(ny)),
                 z = (k - cz) / (0.48 * double(nz));
    return x * x + y * y + z * z <= 1;
  };
  std::vector<std::array<double, 3>> seeds;
  while (int(seeds.size()) < labels) {
    const std::array<double, 3> s{uniform() * double(nx), uniform() * double(ny),
                                  uniform() * double(nz)};
    if (in_body(s[0], s[1], s[2])) seeds.push_back(s);
  }
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        if (!in_body(double(i), double(j), double(k))) continue;
        double best = 1e300;
        int label = 0;
        for (int s = 0; s < labels; ++s) {
          const double dx = (double(i) - seeds[s][0]) * 0.8, dy = (double(j) - seeds[s][1]) * 0.8,
                       dz = double(k) - seeds[s][2];
          const double d = dx * dx + dy * dy + dz * dz;
          if (d < best) {
            best = d;
            label = s + 1;
          }
        }
        map.at(i, j, k) = float(label);
      }
    }
  }
  return map;
}

}  // namespace

int main(int argc, char** argv) {
  unsigned threads = 0;
  std::vector<long long> numbers;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--help" || arg == "-h") {
      std::printf("usage: label_map_bench [--threads N] [NX NY NZ LABELS]\n"
                  "  default 256 256 160 100; N: threads (default all cores)\n");
      return 0;
    }
    if (arg == "--threads" && a + 1 < argc) {
      threads = static_cast<unsigned>(std::atoi(argv[++a]));
      continue;
    }
    numbers.push_back(std::atoll(argv[a]));
  }
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  const std::int64_t nx = numbers.size() > 0 ? numbers[0] : 256;
  const std::int64_t ny = numbers.size() > 1 ? numbers[1] : 256;
  const std::int64_t nz = numbers.size() > 2 ? numbers[2] : 160;
  const int labels = numbers.size() > 3 ? static_cast<int>(numbers[3]) : 100;
  const core::Volume map = label_map(nx, ny, nz, labels);
  app::PipelineOptions pipeline;  // convert's defaults: tm, closed borders, default finishing
  pipeline.threads = threads;

  // Every figure is the faster of two runs: the first run of each also pays for first-touch
  // page faults that a long-running process (or the second label) no longer sees.
  app::SurfaceSpec whole{"body", "body", 0.5, std::nullopt, false, 0, false, false, {}};
  app::SurfaceResult body;
  double whole_ms = 1e300;
  for (int repeat = 0; repeat < 2; ++repeat) {
    const auto start = Clock::now();
    body = app::make_surface(map, whole, pipeline);
    whole_ms = std::min(whole_ms, ms_since(start));
  }

  auto start = Clock::now();

  start = Clock::now();
  const auto census = app::label_census(map);
  const double census_ms = ms_since(start);
  const double sigma = 0.5 * 0.8;
  std::vector<app::LabelTask> tasks;
  for (const auto& [label, extent] : census) {
    tasks.push_back({&map, label, extent,
                     {"l", "l", app::detail::kLabelIso, std::nullopt, false, 0, false, false, {}}});
  }
  struct Run {
    double ms = 0;
    double field_ms = 0, extract_ms = 0, check_ms = 0;  // summed over labels (CPU-like)
    std::size_t triangles = 0, invalid = 0;
    std::vector<app::LabelSurface> surfaces;
  };
  auto all_labels = [&](unsigned n) {
    Run run;
    run.ms = 1e300;
    for (int repeat = 0; repeat < 2; ++repeat) {
      const auto t0 = Clock::now();
      run.surfaces = app::extract_label_surfaces(tasks, sigma, pipeline, n);
      run.ms = std::min(run.ms, ms_since(t0) + census_ms);
    }
    for (const auto& s : run.surfaces) {
      double steps = 0;
      for (const auto& step : s.result.steps) {
        steps += step.milliseconds + step.check_milliseconds;
        run.extract_ms += step.milliseconds;
        run.check_ms += step.check_milliseconds;
      }
      run.field_ms += s.milliseconds - steps;
      run.triangles += s.result.mesh.triangles.size();
      run.invalid += s.result.steps.back().check.closed_manifold() ? 0 : 1;
    }
    return run;
  };
  // extract_label_surfaces on one worker: labels in turn, each extraction on `threads`.
  const Run serial = all_labels(1);
  const Run parallel = all_labels(threads);
  bool identical = true;
  for (std::size_t t = 0; t < tasks.size(); ++t) {
    identical = identical &&
                serial.surfaces[t].result.mesh.positions == parallel.surfaces[t].result.mesh.positions &&
                serial.surfaces[t].result.mesh.triangles == parallel.surfaces[t].result.mesh.triangles;
  }
  std::printf("label map %lldx%lldx%lld (%.1f M voxels), %zu labels, %u threads\n", (long long)nx,
              (long long)ny, (long long)nz, double(map.size().voxels()) / 1e6, census.size(),
              threads);
  std::printf("  whole volume, one extraction:        %8.0f ms, %zu triangles, %s\n", whole_ms,
              body.mesh.triangles.size(),
              body.steps.back().check.closed_manifold() ? "closed manifold" : "NOT closed");
  std::printf("  all labels one after another (census %.0f ms): %8.0f ms, %zu triangles, %zu not "
              "closed manifold\n",
              census_ms, serial.ms, serial.triangles, serial.invalid);
  std::printf("    of which fields %.0f ms, extraction %.0f ms, checks %.0f ms; whole volume: "
              "extraction %.0f ms, check %.0f ms\n",
              serial.field_ms, serial.extract_ms, serial.check_ms,
              body.steps.front().milliseconds, body.steps.front().check_milliseconds);
  std::printf("  all labels in parallel:                        %8.0f ms, %zu triangles, %zu not "
              "closed manifold, %s\n",
              parallel.ms, parallel.triangles, parallel.invalid,
              identical ? "identical surfaces" : "DIFFERENT surfaces");
  std::printf("  ratio all labels / one extraction: %.2f one after another, %.2f in parallel\n",
              serial.ms / whole_ms, parallel.ms / whole_ms);
  return serial.invalid == 0 && parallel.invalid == 0 && identical ? 0 : 1;
}
