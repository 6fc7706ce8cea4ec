// Volumes for the core tests: analytic fields sampled on the lattice, and noise.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include "core/cube_tables.h"
#include "core/volume.h"

namespace typemerge::core::test {

// Samples f(i, j, k) at every voxel index.
template <typename Field>
Volume sample_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz, Field f) {
  Volume volume({nx, ny, nz}, IndexToPatient{});
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        volume.at(i, j, k) = static_cast<float>(
            f(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)));
      }
    }
  }
  return volume;
}

// R − |p − c|: positive inside the ball of radius R about c.
inline Volume sphere_volume(std::int64_t n, double radius, double cx, double cy, double cz) {
  return sample_volume(n, n, n, [=](double x, double y, double z) {
    return radius - std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz));
  });
}

// Uniform noise in [0, 1).
inline Volume noise_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  Volume volume({nx, ny, nz}, IndexToPatient{});
  for (float& v : volume.samples()) v = uniform(rng);
  return volume;
}

// Values for cube index c on the 8 corners of the cube at `origin`: inside in [iso, iso+1),
// outside in [iso−1, iso) for iso 0. Exactly iso is allowed (tie rule) and tested elsewhere.
inline void set_cube(Volume& volume, unsigned c, std::int64_t x0, std::int64_t y0,
                     std::int64_t z0, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int v = 0; v < 8; ++v) {
    const auto& o = kCubeVertexOffset[v];
    const float magnitude = u(rng);
    volume.at(x0 + o[0], y0 + o[1], z0 + o[2]) =
        ((c >> v) & 1u) ? magnitude : -std::max(magnitude, 1e-6f);
  }
}

}  // namespace typemerge::core::test
