// label_map_bench [NX NY NZ LABELS]: label mode's cost against one whole-volume extraction.
//
// A synthetic label map (default 256 × 256 × 160, 0.8 × 0.8 × 1 mm): a body ellipsoid cut into
// LABELS (default 100) touching Voronoi cells around jittered seeds, background outside, as an
// organ segmentation looks. Timed, as `convert --labels all` does them (app/label_mode.h): the
// census (one pass), then per label its smoothed, clamped field on its padded box and the
// extraction with finishing (make_surface, tm); against make_surface on the whole map once
// (the body's surface at 0.5: one extraction of the whole volume). Prints both times, the
// ratio, triangles and validity.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "app/label_census.h"
#include "app/label_mode.h"
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
  const std::int64_t nx = argc > 1 ? std::atoll(argv[1]) : 256;
  const std::int64_t ny = argc > 2 ? std::atoll(argv[2]) : 256;
  const std::int64_t nz = argc > 3 ? std::atoll(argv[3]) : 160;
  const int labels = argc > 4 ? std::atoi(argv[4]) : 100;
  const core::Volume map = label_map(nx, ny, nz, labels);
  app::PipelineOptions pipeline;  // convert's defaults: tm, closed borders, default finishing

  auto start = Clock::now();
  app::SurfaceSpec whole{"body", "body", 0.5, std::nullopt, false, 0, false, false, {}};
  const app::SurfaceResult body = app::make_surface(map, whole, pipeline);
  const double whole_ms = ms_since(start);

  start = Clock::now();
  const auto census = app::label_census(map);
  const double census_ms = ms_since(start);
  const double sigma = 0.5 * 0.8;
  std::size_t triangles = 0, invalid = 0;
  for (const auto& [label, extent] : census) {
    const core::Volume field = app::detail::label_field(map, label, extent, sigma);
    app::SurfaceSpec spec{"l",   "l", app::detail::kLabelIso, std::nullopt, false, 0, false,
                          false, {}};
    const app::SurfaceResult r = app::make_surface(field, spec, pipeline);
    triangles += r.mesh.triangles.size();
    invalid += r.steps.back().check.closed_manifold() ? 0 : 1;
  }
  const double labels_ms = ms_since(start);
  std::printf("label map %lldx%lldx%lld (%.1f M voxels), %zu labels\n", (long long)nx,
              (long long)ny, (long long)nz, double(map.size().voxels()) / 1e6, census.size());
  std::printf("  whole volume, one extraction: %8.0f ms, %zu triangles, %s\n", whole_ms,
              body.mesh.triangles.size(),
              body.steps.back().check.closed_manifold() ? "closed manifold" : "NOT closed");
  std::printf("  all labels (census %.0f ms):   %8.0f ms, %zu triangles, %zu not closed manifold\n",
              census_ms, labels_ms, triangles, invalid);
  std::printf("  ratio all labels / one extraction: %.2f\n", labels_ms / whole_ms);
  return invalid == 0 ? 0 : 1;
}
