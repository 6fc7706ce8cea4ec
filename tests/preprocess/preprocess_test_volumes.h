// Volumes for the preprocess tests: fields given in patient mm, noise, and simple statistics.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "core/volume.h"

namespace typemerge::preprocess::test {

inline core::IndexToPatient spacing_geometry(double sx, double sy, double sz,
                                             core::Vec3 origin = {0, 0, 0}) {
  core::IndexToPatient geometry;
  geometry.origin = origin;
  geometry.axes = {{{sx, 0, 0}, {0, sy, 0}, {0, 0, sz}}};
  return geometry;
}

// Samples f(patient position) at every voxel centre.
template <typename Field>
core::Volume patient_field(core::VolumeSize size, const core::IndexToPatient& geometry, Field f) {
  core::Volume volume(size, geometry);
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 0; i < size.nx; ++i) {
        const core::Vec3 p =
            geometry.apply(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
        volume.at(i, j, k) = static_cast<float>(f(p));
      }
    }
  }
  return volume;
}

inline void add_gaussian_noise(core::Volume& volume, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  for (float& v : volume.samples()) v += static_cast<float>(normal(rng));
}

// Variance of the voxels at least `border` voxels from every face.
inline double interior_variance(const core::Volume& volume, std::int64_t border) {
  const auto& s = volume.size();
  double sum = 0, sum2 = 0;
  std::int64_t n = 0;
  for (std::int64_t k = border; k < s.nz - border; ++k) {
    for (std::int64_t j = border; j < s.ny - border; ++j) {
      for (std::int64_t i = border; i < s.nx - border; ++i) {
        const double v = volume.at(i, j, k);
        sum += v;
        sum2 += v * v;
        ++n;
      }
    }
  }
  const double mean = sum / static_cast<double>(n);
  return sum2 / static_cast<double>(n) - mean * mean;
}

// A patient on a scanner table, as CT shows one: an elliptic body with lungs and a spine, a
// foam pad under the back, a curved table top touching the pad and the body's side, rails,
// an arm rest touching the image's edge, and noise.
// n × n pixels over a 205 mm field of view, slices 2.5 mm apart.
inline core::Volume body_lying_on_a_table(std::int64_t n, std::int64_t nz) {
  const double pixel = 204.8 / static_cast<double>(n);
  const core::IndexToPatient geometry = spacing_geometry(pixel, pixel, 2.5, {-102, -102, 0});
  core::Volume volume = patient_field({n, n, nz}, geometry, [](const core::Vec3& p) {
    const double x = p[0], y = p[1], z = p[2];
    const double body = (x / 80) * (x / 80) + ((y + 10) / 55) * ((y + 10) / 55);
    if (body <= 1) {
      const double lung_l = std::hypot((x - 35) / 22, (y + 15) / 28);
      const double lung_r = std::hypot((x + 35) / 22, (y + 15) / 28);
      if (z > 20 && (lung_l < 1 || lung_r < 1)) return -820.0;
      if (std::hypot(x, y - 30) < 12) return 700.0;  // spine
      return body > 0.85 ? -90.0 : 40.0;             // fat under the skin
    }
    if (y > 45 && y < 52 && std::abs(x) < 90) return -600.0;          // foam pad
    const double table = 52 + 0.002 * x * x;
    if (y > table && y < table + 4 && std::abs(x) < 95) return 250.0;  // table top
    if (y > 70 && y < 76 && (std::abs(x - 40) < 3 || std::abs(x + 40) < 3)) return 1400.0;
    if (x > 95 && std::abs(y + 20) < 6) return 60.0;                  // arm rest at the edge
    return -1000.0;
  });
  add_gaussian_noise(volume, 25.0, 3);
  return volume;
}

}  // namespace typemerge::preprocess::test
