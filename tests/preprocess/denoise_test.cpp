// Denoising filters: each test fails if the filter did nothing, or did it only in-plane.
#include "preprocess/denoise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "preprocess_test_volumes.h"

namespace typemerge::preprocess {
namespace {

using core::Volume;
using test::add_gaussian_noise;
using test::interior_variance;
using test::spacing_geometry;

Volume constant_volume(core::VolumeSize size, const core::IndexToPatient& geometry, float value) {
  Volume volume(size, geometry);
  for (float& v : volume.samples()) v = value;
  return volume;
}

// The sampled, normalised Gaussian written independently of the implementation.
std::vector<double> sampled_gaussian(double sigma, int radius) {
  std::vector<double> w;
  double sum = 0;
  for (int t = -radius; t <= radius; ++t) {
    w.push_back(std::exp(-0.5 * t * t / (sigma * sigma)));
    sum += w.back();
  }
  for (double& x : w) x /= sum;
  return w;
}

// White noise of variance v becomes v · Π_axes Σ w² after a separable filter.
TEST(GaussianFilter, ReducesWhiteNoiseVarianceByTheKernelFactor) {
  // Spacing 0.5 × 0.5 × 1 mm with sigma 1 mm: sigma (2, 2, 1) voxels, radius (6, 6, 3).
  Volume volume = constant_volume({96, 96, 48}, spacing_geometry(0.5, 0.5, 1.0), 100.0f);
  add_gaussian_noise(volume, 20.0, 1);
  const double before = interior_variance(volume, 6);
  const StepResult result = gaussian_filter(volume, {.sigma_mm = 1.0});
  const double after = interior_variance(result.volume, 6);

  double expected = 1;
  for (const auto& [sigma, radius] : {std::pair{2.0, 6}, std::pair{2.0, 6}, std::pair{1.0, 3}}) {
    double sum_squares = 0;
    for (double w : sampled_gaussian(sigma, radius)) sum_squares += w * w;
    expected *= sum_squares;
  }
  EXPECT_NEAR(expected, 0.00561, 0.0002);  // 1/(2√π)³ / (2·2·1)
  EXPECT_NEAR(after / before, expected, 0.15 * expected);
  EXPECT_EQ(result.record.step, "gaussian");
  ASSERT_NE(result.record.parameter("sigma_voxels_i"), nullptr);
  EXPECT_EQ(*result.record.parameter("sigma_voxels_i"), "2");
  EXPECT_EQ(*result.record.parameter("sigma_voxels_k"), "1");
}

TEST(GaussianFilter, KeepsAConstantVolumeConstant) {
  const Volume volume = constant_volume({20, 17, 9}, spacing_geometry(0.7, 0.7, 2.5), -312.5f);
  const StepResult result = gaussian_filter(volume, {.sigma_mm = 1.5});
  ASSERT_EQ(result.volume.size(), volume.size());
  for (float v : result.volume.samples()) ASSERT_NEAR(v, -312.5f, 1e-3f);
}

// A step between slices is blurred by exactly the k kernel: the filter is 3D.
TEST(GaussianFilter, BlursAStepAlongTheSliceAxis) {
  const core::VolumeSize size{12, 10, 20};
  Volume volume(size, spacing_geometry(1, 1, 1));
  for (std::int64_t k = 10; k < 20; ++k) {
    for (std::int64_t j = 0; j < 10; ++j) {
      for (std::int64_t i = 0; i < 12; ++i) volume.at(i, j, k) = 1000;
    }
  }
  const StepResult result = gaussian_filter(volume, {.sigma_mm = 1.0});
  const std::vector<double> w = sampled_gaussian(1.0, 3);
  const double below = 1000 * (w[4] + w[5] + w[6]);  // slice 9 sees slices 10..12
  for (std::int64_t j = 0; j < 10; ++j) {
    for (std::int64_t i = 0; i < 12; ++i) {
      EXPECT_NEAR(result.volume.at(i, j, 9), below, 1e-2);
      EXPECT_NEAR(result.volume.at(i, j, 10), 1000 - below, 1e-2);
      EXPECT_NEAR(result.volume.at(i, j, 2), 0, 1e-3);
    }
  }
  EXPECT_GT(below, 200);
}

TEST(GaussianFilter, RejectsInvalidParameters) {
  const Volume volume = constant_volume({4, 4, 4}, spacing_geometry(1, 1, 1), 0);
  EXPECT_THROW(gaussian_filter(volume, {.sigma_mm = -1}), std::invalid_argument);
  EXPECT_THROW(gaussian_filter(volume, {.sigma_mm = 0}), std::invalid_argument);
  EXPECT_THROW(gaussian_filter(volume, {.sigma_mm = NAN}), std::invalid_argument);
  EXPECT_THROW(gaussian_filter(volume, {.sigma_mm = 1, .truncate = 0.5}), std::invalid_argument);
  try {
    gaussian_filter(volume, {.sigma_mm = -2});
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("sigma_mm"), std::string::npos) << error.what();
  }
}

// The memory claim: a volume passed with std::move is filtered in its own buffer.
TEST(Denoise, FiltersAMovedVolumeInPlace) {
  Volume volume = constant_volume({16, 12, 6}, spacing_geometry(1, 1, 1), 5.0f);
  add_gaussian_noise(volume, 10.0, 2);
  const float* buffer = volume.samples().data();
  StepResult result = gaussian_filter(std::move(volume), {});
  EXPECT_EQ(result.volume.samples().data(), buffer);
  result = median_filter(std::move(result.volume), {});
  EXPECT_EQ(result.volume.samples().data(), buffer);
  result = bilateral_filter(std::move(result.volume), {});
  EXPECT_EQ(result.volume.samples().data(), buffer);
}

// An int16 volume is filtered slice by slice into a new float volume, its storage released
// in 2 MiB blocks as it is read: the result must equal filtering the same values as floats.
// 192×160×104 int16 samples are 6.1 MiB, so blocks are released mid-volume, inside slices.
TEST(Denoise, Int16InputGivesTheFloatResult) {
  Volume volume = Volume::uninitialized({192, 160, 104}, spacing_geometry(0.8, 0.8, 1.25),
                                        core::SampleType::int16);
  std::uint32_t state = 12345;
  for (std::int64_t k = 0; k < 104; ++k) {
    for (std::int64_t j = 0; j < 160; ++j) {
      for (std::int64_t i = 0; i < 192; ++i) {
        state = state * 1664525u + 1013904223u;
        const int noise = static_cast<int>(state >> 24) - 128;  // −128…127
        const int base = (i - 96) * (i - 96) + (j - 80) * (j - 80) < 50 * 50 ? 1200 : -900;
        volume.int16_slice(k)[j * 192 + i] = static_cast<std::int16_t>(base + noise);
      }
    }
  }
  Volume as_float = volume;
  as_float.to_float();
  auto same = [](const Volume& a, const Volume& b) {
    ASSERT_FALSE(a.holds_int16());
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(0, std::memcmp(a.samples().data(), b.samples().data(), a.sample_bytes()));
    EXPECT_EQ(a.geometry().axes, b.geometry().axes);
  };
  same(gaussian_filter(volume, {}).volume, gaussian_filter(as_float, {}).volume);
  same(median_filter(volume, {}).volume, median_filter(as_float, {}).volume);
  same(median_filter(volume, {.in_plane_size = 5, .along_slices = false}).volume,
       median_filter(as_float, {.in_plane_size = 5, .along_slices = false}).volume);
  same(bilateral_filter(std::move(volume), {}).volume, bilateral_filter(as_float, {}).volume);
}

TEST(GaussianFilter, ReturnsAnEmptyVolumeUnchanged) {
  const StepResult result = gaussian_filter(Volume({0, 0, 0}, {}), {});
  EXPECT_EQ(result.volume.size().voxels(), 0);
}

TEST(MedianFilter, RemovesIsolatedSaltAndPepper) {
  Volume volume = constant_volume({40, 40, 16}, spacing_geometry(0.7, 0.7, 2), 40.0f);
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::size_t> pick(0, volume.samples().size() - 1);
  for (int n = 0; n < 200; ++n) volume.samples()[pick(rng)] = (n % 2) ? 3000.0f : -1024.0f;
  const StepResult result = median_filter(volume, {});
  for (float v : result.volume.samples()) ASSERT_EQ(v, 40.0f);
  EXPECT_EQ(result.record.step, "median");
}

// A 5×5 plate one slice thick survives any in-plane median; only the k pass removes it.
TEST(MedianFilter, RemovesAPlateIsolatedAlongTheSliceAxis) {
  Volume volume = constant_volume({16, 16, 9}, spacing_geometry(1, 1, 1), 0.0f);
  for (std::int64_t j = 5; j < 10; ++j) {
    for (std::int64_t i = 5; i < 10; ++i) volume.at(i, j, 4) = 1000;
  }
  const StepResult in_plane = median_filter(volume, {.in_plane_size = 3, .along_slices = false});
  EXPECT_EQ(in_plane.volume.at(7, 7, 4), 1000.0f);
  const StepResult full = median_filter(volume, {.in_plane_size = 3, .along_slices = true});
  for (float v : full.volume.samples()) ASSERT_EQ(v, 0.0f);
}

TEST(MedianFilter, KeepsAStepEdgeExactly) {
  Volume volume(core::VolumeSize{20, 20, 8}, spacing_geometry(1, 1, 1));
  for (std::int64_t k = 0; k < 8; ++k) {
    for (std::int64_t j = 0; j < 20; ++j) {
      for (std::int64_t i = 10; i < 20; ++i) volume.at(i, j, k) = 700;
    }
  }
  const StepResult result = median_filter(volume, {.in_plane_size = 5});
  EXPECT_EQ(result.volume.samples(), volume.samples());
}

TEST(MedianFilter, RejectsUnsupportedKernelSizes) {
  const Volume volume = constant_volume({8, 8, 3}, spacing_geometry(1, 1, 1), 0);
  EXPECT_THROW(median_filter(volume, {.in_plane_size = 4}), std::invalid_argument);
  EXPECT_THROW(median_filter(volume, {.in_plane_size = 7}), std::invalid_argument);
}

double gaussian_noise_ratio(double sigma_mm, const Volume& noisy, double variance) {
  return interior_variance(gaussian_filter(noisy, {.sigma_mm = sigma_mm}).volume, 8) / variance;
}

// Mean |filtered − ideal| over the voxels within two of the edge plane i = 24 | 25.
double edge_error(const Volume& filtered) {
  double sum = 0;
  std::int64_t n = 0;
  for (std::int64_t k = 4; k < filtered.size().nz - 4; ++k) {
    for (std::int64_t j = 8; j < filtered.size().ny - 8; ++j) {
      for (std::int64_t i = 22; i < 28; ++i) {
        sum += std::abs(filtered.at(i, j, k) - (i < 25 ? 0.0 : 1000.0));
        ++n;
      }
    }
  }
  return sum / static_cast<double>(n);
}

TEST(BilateralFilter, KeepsAnEdgeSharperThanAGaussianOfEqualNoiseReduction) {
  const core::VolumeSize size{50, 48, 24};
  const auto geometry = spacing_geometry(1, 1, 1);
  Volume flat = constant_volume(size, geometry, 0.0f);
  add_gaussian_noise(flat, 20.0, 3);
  const double variance = interior_variance(flat, 8);
  const BilateralOptions options{.sigma_mm = 1.5, .sigma_hu = 60};
  const double bilateral_ratio =
      interior_variance(bilateral_filter(flat, options).volume, 8) / variance;
  EXPECT_LT(bilateral_ratio, 0.1);  // it denoises: 20 HU noise → about 3 HU

  // The Gaussian sigma with the same noise reduction, by bisection (the ratio falls with sigma).
  double low = 0.2, high = 5.0;
  for (int iteration = 0; iteration < 14; ++iteration) {
    const double mid = 0.5 * (low + high);
    (gaussian_noise_ratio(mid, flat, variance) > bilateral_ratio ? low : high) = mid;
  }
  const double gaussian_sigma = high;
  EXPECT_NEAR(gaussian_noise_ratio(gaussian_sigma, flat, variance), bilateral_ratio,
              0.05 * bilateral_ratio);

  Volume edge = flat;
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 25; i < size.nx; ++i) edge.at(i, j, k) += 1000;
    }
  }
  const double bilateral_error = edge_error(bilateral_filter(edge, options).volume);
  const double gaussian_error =
      edge_error(gaussian_filter(edge, {.sigma_mm = gaussian_sigma}).volume);
  EXPECT_LT(bilateral_error, 0.25 * gaussian_error)
      << "bilateral " << bilateral_error << " HU, Gaussian(" << gaussian_sigma << " mm) "
      << gaussian_error << " HU";
}

// Noise in slices alone is reduced further by the k pass: the filter is 3D.
TEST(BilateralFilter, FiltersAlongTheSliceAxisToo) {
  Volume flat = constant_volume({40, 40, 20}, spacing_geometry(1, 1, 1), 0.0f);
  add_gaussian_noise(flat, 20.0, 5);
  const double in_plane =
      interior_variance(bilateral_filter(flat, {.along_slices = false}).volume, 4);
  const double full = interior_variance(bilateral_filter(flat, {.along_slices = true}).volume, 4);
  EXPECT_LT(full, 0.8 * in_plane);
}

TEST(BilateralFilter, RejectsInvalidParameters) {
  const Volume volume = constant_volume({8, 8, 3}, spacing_geometry(1, 1, 1), 0);
  EXPECT_THROW(bilateral_filter(volume, {.sigma_mm = -1}), std::invalid_argument);
  EXPECT_THROW(bilateral_filter(volume, {.sigma_mm = 1, .sigma_hu = 0}), std::invalid_argument);
}

TEST(BilateralFilter, WarnsAboutNonSquarePixels) {
  const Volume volume = constant_volume({8, 8, 3}, spacing_geometry(0.5, 1.0, 1), 0);
  EXPECT_EQ(bilateral_filter(volume, {}).record.warnings.size(), 1u);
}

}  // namespace
}  // namespace typemerge::preprocess
