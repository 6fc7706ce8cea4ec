// synthetic_volume: the CT-like test volume the benchmarks share (extract_bench,
// pipeline_bench), so their figures for "synthetic NXxNYxNZ" are of the same samples.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/volume.h"

namespace typemerge::bench {

// A CT-like synthetic volume: a body ellipsoid of soft tissue with a fat layer, a bony shell
// and a few bone pieces, in air, with deterministic noise (σ ≈ 20 HU). 0.7 mm in-plane, 1 mm
// slices.
inline core::Volume synthetic_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
  core::IndexToPatient geometry;
  geometry.axes = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 1.0}}};
  core::Volume volume({nx, ny, nz}, geometry);
  std::uint64_t state = 0x9E3779B97F4A7C15ull;
  auto noise = [&] {  // sum of 4 uniforms: cheap, deterministic, roughly normal
    double sum = 0;
    for (int n = 0; n < 4; ++n) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      sum += static_cast<double>(state >> 11) * (1.0 / 9007199254740992.0) - 0.5;
    }
    return sum * 20.0 / 0.577;
  };
  const double cx = double(nx) / 2, cy = double(ny) / 2, cz = double(nz) / 2;
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      float* row = volume.slice(k) + j * nx;
      for (std::int64_t i = 0; i < nx; ++i) {
        const double x = (double(i) - cx) / (0.42 * double(nx)),
                     y = (double(j) - cy) / (0.36 * double(ny)),
                     z = (double(k) - cz) / (0.48 * double(nz));
        const double r = std::sqrt(x * x + y * y + 0.3 * z * z);
        double hu = -1000;
        if (r < 1.0) hu = r > 0.95 ? -90 : 40;                      // skin and fat
        if (r > 0.70 && r < 0.76) hu = 1100;                        // bony shell
        const double sx = x - 0.3 * std::sin(6 * z), sy = y + 0.2;  // a winding "spine"
        if (sx * sx + sy * sy < 0.01) hu = 600;
        for (int b = 0; b < 6; ++b) {  // small bone pieces
          const double bx = x + 0.4 - 0.15 * b, by = y - 0.3, bz = z - 0.5 + 0.2 * b;
          if (bx * bx + by * by + bz * bz < 0.002) hu = 900;
        }
        row[i] = static_cast<float>(hu + noise());
      }
    }
  }
  return volume;
}

}  // namespace typemerge::bench
