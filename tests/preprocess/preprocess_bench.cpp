// Time of each preprocessing step on a CT-sized synthetic volume, with what it did beside it.
//   preprocess_bench [nx ny nz]     (default 512 512 134, spacing 0.78 × 0.78 × 1.25 mm)
// A body (an elliptic cylinder of 40 HU with a 700 HU "bone" rod) in air, plus N(0, 20 HU)
// noise. The noise figure is the standard deviation inside the body before and after.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

#include "preprocess/crop.h"
#include "preprocess/denoise.h"
#include "preprocess/resample.h"

namespace {

using typemerge::core::Volume;
using namespace typemerge::preprocess;

Volume make_body(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
  typemerge::core::IndexToPatient geometry;
  geometry.origin = {-200, -200, 0};
  geometry.axes = {{{0.78, 0, 0}, {0, 0.78, 0}, {0, 0, 1.25}}};
  Volume volume({nx, ny, nz}, geometry);
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 20.0f);
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        const double x = (static_cast<double>(i) - 0.5 * static_cast<double>(nx)) /
                         (0.4 * static_cast<double>(nx));
        const double y = (static_cast<double>(j) - 0.5 * static_cast<double>(ny)) /
                         (0.3 * static_cast<double>(ny));
        const double rod = std::hypot(x - 0.3, y);
        const float hu = x * x + y * y > 1 ? -1000.0f : rod < 0.15 ? 700.0f : 40.0f;
        volume.at(i, j, k) = hu + noise(rng);
      }
    }
  }
  return volume;
}

// Standard deviation of a 40×40 patch at the body's centre-left, all slices.
double body_noise(const Volume& volume) {
  const auto& s = volume.size();
  const std::int64_t i0 = s.nx * 2 / 5, j0 = s.ny / 2 - s.ny / 25;
  const std::int64_t w = std::max<std::int64_t>(2, s.nx / 13);
  double sum = 0, sum2 = 0, n = 0;
  for (std::int64_t k = 0; k < s.nz; ++k) {
    for (std::int64_t j = j0; j < j0 + w; ++j) {
      for (std::int64_t i = i0; i < i0 + w; ++i) {
        sum += volume.at(i, j, k);
        sum2 += double(volume.at(i, j, k)) * volume.at(i, j, k);
        n += 1;
      }
    }
  }
  return std::sqrt(sum2 / n - (sum / n) * (sum / n));
}

template <typename Step>
void run(const char* name, const Volume& input, Step step) {
  const auto start = std::chrono::steady_clock::now();
  const StepResult result = step(input);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::printf("%-20s %8.0f ms  %s  noise %.1f → %.1f HU\n  %s\n", name, ms,
              typemerge::preprocess::detail::format_size(result.volume.size()).c_str(),
              body_noise(input), body_noise(result.volume), result.record.description.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  const std::int64_t nx = argc > 3 ? std::atoll(argv[1]) : 512;
  const std::int64_t ny = argc > 3 ? std::atoll(argv[2]) : 512;
  const std::int64_t nz = argc > 3 ? std::atoll(argv[3]) : 134;
  const Volume volume = make_body(nx, ny, nz);
  std::printf("input %s, %.0f MB; times include one copy of the input for the in-place filters\n",
              detail::format_size(volume.size()).c_str(),
              static_cast<double>(volume.size().voxels()) * 4 / 1e6);
  run("gaussian 0.7 mm", volume,
      [](const Volume& v) { return gaussian_filter(v, {.sigma_mm = 0.7}); });
  run("median 3×3×3", volume, [](const Volume& v) { return median_filter(v, {}); });
  run("median 5×5×3", volume,
      [](const Volume& v) { return median_filter(v, {.in_plane_size = 5}); });
  run("bilateral 1 mm 60HU", volume, [](const Volume& v) { return bilateral_filter(v, {}); });
  run("isotropic 0.78 mm", volume, [](const Volume& v) { return resample_isotropic(v); });
  run("resample 1 mm", volume, [](const Volume& v) {
    return resample(v, {.voxel_size_mm = {1, 1, 1}});
  });
  run("downsample ×2", volume, [](const Volume& v) { return downsample(v, {.factor = 2}); });
  run("crop_to_tissue", volume, [](const Volume& v) { return crop_to_tissue(v, {}); });
  run("crop box", volume, [](const Volume& v) { return crop(v, {{64, 64, 10}, {448, 448, 124}}); });
  return 0;
}
