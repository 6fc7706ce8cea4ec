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

}  // namespace typemerge::preprocess::test
