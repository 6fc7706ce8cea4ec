// Denoising: OpenCV per slice, then a hand-written 1D pass along the slice axis k.
//
// Why the k pass is written by hand: OpenCV filters 2D images; along k the samples of one
// voxel column are nx·ny floats apart. Rather than transposing the volume (a second full
// copy), the k pass gathers, for one row j, the nz×nx plane of that row across all slices into
// a scratch buffer and writes the filtered values back in place. The inner loops then run over
// i, contiguous in both buffers, and the border rule (replicate) matches the in-plane pass.
#include "preprocess/denoise.h"

#include <algorithm>
#include <cassert>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "preprocess/consumed_input.h"

namespace typemerge::preprocess {
namespace {

using core::Volume;

void assert_volume(const Volume& volume) {
  assert(volume.sample_bytes() ==
         static_cast<std::size_t>(volume.size().voxels()) * (volume.holds_int16() ? 2 : 4));
  assert(volume.size().nx <= INT_MAX && volume.size().ny <= INT_MAX);
  for (int axis = 0; axis < 3; ++axis) assert(volume.geometry().spacing(axis) > 0);
  (void)volume;
}

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument(message);
}

bool positive(double value) { return std::isfinite(value) && value > 0; }

// A view of slice k as a one-channel float image (no copy).
cv::Mat slice_image(Volume& volume, std::int64_t k) {
  return cv::Mat(static_cast<int>(volume.size().ny), static_cast<int>(volume.size().nx), CV_32FC1,
                 volume.slice(k));
}

// Runs `filter(source, destination)` on every slice; the result is float storage.
//   float input: in place, each slice copied to a scratch image first (cv::medianBlur and
//     cv::bilateralFilter do not work in place);
//   int16 input: each slice converted into the scratch image and filtered into a new float
//     volume, the input's storage returned to the OS as its slices are read
//     (ConsumedInput), so that the peak is the float output, not output + input.
// The values are the same either way: an int16 sample converts to the float of its integer.
template <typename Filter>
void filter_slices(Volume& volume, const char* step, Filter filter) {
  const core::VolumeSize size = volume.size();
  const int rows = static_cast<int>(size.ny), columns = static_cast<int>(size.nx);
  cv::Mat scratch(rows, columns, CV_32FC1);
  try {
    if (!volume.holds_int16()) {
      for (std::int64_t k = 0; k < size.nz; ++k) {
        cv::Mat slice = slice_image(volume, k);
        slice.copyTo(scratch);
        filter(scratch, slice);
        assert(slice.data == reinterpret_cast<uchar*>(volume.slice(k)));  // no reallocation
      }
      return;
    }
    Volume output = Volume::uninitialized(size, volume.geometry());
    const std::int16_t* input = volume.int16_samples().data();
    const auto slice_voxels = static_cast<std::size_t>(size.nx * size.ny);
    ConsumedInput consumed(input);
    for (std::int64_t k = 0; k < size.nz; ++k) {
      const std::int16_t* source = input + static_cast<std::size_t>(k) * slice_voxels;
      std::copy(source, source + slice_voxels, scratch.ptr<float>());
      cv::Mat slice = slice_image(output, k);
      filter(scratch, slice);
      assert(slice.data == reinterpret_cast<uchar*>(output.slice(k)));  // no reallocation
      consumed.consumed(static_cast<std::size_t>(k + 1) * slice_voxels * sizeof(std::int16_t));
    }
    volume = std::move(output);
  } catch (const cv::Exception& error) {
    throw std::runtime_error(std::string(step) + ": OpenCV: " + error.what());
  }
}

// Runs `filter(plane, j)` for every row j, with plane[k·nx + i] = volume(i, j, k) gathered
// into a scratch buffer; the filter writes its results into the volume.
template <typename Filter>
void filter_along_slices(Volume& volume, Filter filter) {
  const auto& size = volume.size();
  std::vector<float> plane(static_cast<std::size_t>(size.nx * size.nz));
  for (std::int64_t j = 0; j < size.ny; ++j) {
    for (std::int64_t k = 0; k < size.nz; ++k) {
      std::memcpy(plane.data() + k * size.nx, &volume.at(0, j, k),
                  static_cast<std::size_t>(size.nx) * sizeof(float));
    }
    filter(plane.data(), j);
  }
}

std::int64_t clamp_index(std::int64_t k, std::int64_t n) {
  return std::clamp<std::int64_t>(k, 0, n - 1);
}

// Sampled Gaussian of the given voxel sigma, normalised to sum 1 (OpenCV's formula).
std::vector<double> gaussian_kernel(double sigma, int radius) {
  std::vector<double> weights(static_cast<std::size_t>(2 * radius + 1));
  double sum = 0;
  for (int t = -radius; t <= radius; ++t) {
    const double w = std::exp(-0.5 * t * t / (sigma * sigma));
    weights[static_cast<std::size_t>(t + radius)] = w;
    sum += w;
  }
  for (double& w : weights) w /= sum;
  return weights;
}

float median3(float a, float b, float c) {
  return std::max(std::min(a, b), std::min(std::max(a, b), c));
}

StepRecord start_record(const char* step, const Volume& volume) {
  StepRecord record;
  record.step = step;
  record.size_before = record.size_after = volume.size();
  return record;
}

std::string mm(double value) { return detail::format_number(value) + " mm"; }
std::string voxels3(const double (&v)[3]) {
  return std::string("(") + detail::format_number(v[0]) + ", " + detail::format_number(v[1]) +
         ", " + detail::format_number(v[2]) + ") voxels";
}

}  // namespace

StepResult gaussian_filter(Volume volume, const GaussianOptions& options) {
  require(positive(options.sigma_mm), std::string("gaussian_filter: sigma_mm must be > 0, got ") +
                                          detail::format_number(options.sigma_mm));
  require(std::isfinite(options.truncate) && options.truncate >= 1,
          std::string("gaussian_filter: truncate must be ≥ 1, got ") +
              detail::format_number(options.truncate));
  assert_volume(volume);
  StepRecord record = start_record("gaussian", volume);
  double sigma[3];
  int radius[3];
  for (int axis = 0; axis < 3; ++axis) {
    sigma[axis] = options.sigma_mm / volume.geometry().spacing(axis);
    radius[axis] = std::max(1, static_cast<int>(std::ceil(options.truncate * sigma[axis])));
  }
  record.parameters = {{"sigma_mm", detail::format_number(options.sigma_mm)},
                       {"truncate", detail::format_number(options.truncate)},
                       {"sigma_voxels_i", detail::format_number(sigma[0])},
                       {"sigma_voxels_j", detail::format_number(sigma[1])},
                       {"sigma_voxels_k", detail::format_number(sigma[2])}};
  record.description = std::string("3D Gaussian, sigma ") + mm(options.sigma_mm) + " = " +
                       voxels3(sigma) + ", kernel radius (" + std::to_string(radius[0]) + ", " +
                       std::to_string(radius[1]) + ", " + std::to_string(radius[2]) + ")";
  if (volume.size().voxels() == 0) return {std::move(volume), std::move(record)};

  filter_slices(volume, "gaussian_filter", [&](const cv::Mat& source, cv::Mat& destination) {
    cv::GaussianBlur(source, destination, cv::Size(2 * radius[0] + 1, 2 * radius[1] + 1), sigma[0],
                     sigma[1], cv::BORDER_REPLICATE);
  });
  const auto& size = volume.size();
  if (size.nz > 1) {
    const std::vector<double> kernel = gaussian_kernel(sigma[2], radius[2]);
    filter_along_slices(volume, [&](const float* plane, std::int64_t j) {
      for (std::int64_t k = 0; k < size.nz; ++k) {
        float* out = &volume.at(0, j, k);
        std::fill(out, out + size.nx, 0.0f);
        for (int t = -radius[2]; t <= radius[2]; ++t) {
          const float w = static_cast<float>(kernel[static_cast<std::size_t>(t + radius[2])]);
          const float* in = plane + clamp_index(k + t, size.nz) * size.nx;
          for (std::int64_t i = 0; i < size.nx; ++i) out[i] += w * in[i];
        }
      }
    });
  }
  return {std::move(volume), std::move(record)};
}

StepResult median_filter(Volume volume, const MedianOptions& options) {
  require(
      options.in_plane_size == 3 || options.in_plane_size == 5,
      std::string("median_filter: in_plane_size must be 3 or 5 (cv::medianBlur on float), got ") +
          std::to_string(options.in_plane_size));
  assert_volume(volume);
  StepRecord record = start_record("median", volume);
  const std::string kernel = std::to_string(options.in_plane_size) + "×" +
                             std::to_string(options.in_plane_size) +
                             (options.along_slices ? "×3" : "×1");
  record.parameters = {{"in_plane_size", std::to_string(options.in_plane_size)},
                       {"along_slices", options.along_slices ? "true" : "false"}};
  record.description = std::string("median ") + kernel +
                       " voxels (separable: " + std::to_string(options.in_plane_size) +
                       "² per slice" +
                       (options.along_slices ? ", then 3 along k)" : ", slices independent)");
  if (volume.size().voxels() == 0) return {std::move(volume), std::move(record)};

  filter_slices(volume, "median_filter", [&](const cv::Mat& source, cv::Mat& destination) {
    cv::medianBlur(source, destination, options.in_plane_size);
  });
  const auto& size = volume.size();
  if (options.along_slices && size.nz > 1) {
    filter_along_slices(volume, [&](const float* plane, std::int64_t j) {
      for (std::int64_t k = 0; k < size.nz; ++k) {
        const float* below = plane + clamp_index(k - 1, size.nz) * size.nx;
        const float* here = plane + k * size.nx;
        const float* above = plane + clamp_index(k + 1, size.nz) * size.nx;
        float* out = &volume.at(0, j, k);
        for (std::int64_t i = 0; i < size.nx; ++i) out[i] = median3(below[i], here[i], above[i]);
      }
    });
  }
  return {std::move(volume), std::move(record)};
}

StepResult bilateral_filter(Volume volume, const BilateralOptions& options) {
  require(positive(options.sigma_mm), std::string("bilateral_filter: sigma_mm must be > 0, got ") +
                                          detail::format_number(options.sigma_mm));
  require(positive(options.sigma_hu), std::string("bilateral_filter: sigma_hu must be > 0, got ") +
                                          detail::format_number(options.sigma_hu));
  assert_volume(volume);
  StepRecord record = start_record("bilateral", volume);
  const core::IndexToPatient& geometry = volume.geometry();
  // cv::bilateralFilter has one spatial sigma in pixels: use the mean in-plane spacing.
  const double in_plane_spacing = 0.5 * (geometry.spacing(0) + geometry.spacing(1));
  if (std::abs(geometry.spacing(0) - geometry.spacing(1)) > 0.01 * in_plane_spacing) {
    record.warnings.push_back("bilateral_filter: pixels are not square (" +
                              mm(geometry.spacing(0)) + " × " + mm(geometry.spacing(1)) +
                              "); the in-plane kernel uses their mean");
  }
  const double sigma_plane = options.sigma_mm / in_plane_spacing;
  const double sigma_k = options.sigma_mm / geometry.spacing(2);
  const int radius_plane = std::max(1, static_cast<int>(std::lround(1.5 * sigma_plane)));
  const int radius_k = std::max(1, static_cast<int>(std::lround(1.5 * sigma_k)));
  record.parameters = {{"sigma_mm", detail::format_number(options.sigma_mm)},
                       {"sigma_hu", detail::format_number(options.sigma_hu)},
                       {"along_slices", options.along_slices ? "true" : "false"},
                       {"sigma_voxels_in_plane", detail::format_number(sigma_plane)},
                       {"sigma_voxels_k", detail::format_number(sigma_k)}};
  record.description =
      std::string("bilateral, spatial sigma ") + mm(options.sigma_mm) + " (" +
      detail::format_number(sigma_plane) + " voxels in-plane, radius " +
      std::to_string(radius_plane) + "), range sigma " + detail::format_number(options.sigma_hu) +
      " HU" +
      (options.along_slices ? std::string(", then along k (") + detail::format_number(sigma_k) +
                                  " voxels, radius " + std::to_string(radius_k) + ")"
                            : ", slices independent");
  if (volume.size().voxels() == 0) return {std::move(volume), std::move(record)};

  filter_slices(volume, "bilateral_filter", [&](const cv::Mat& source, cv::Mat& destination) {
    cv::bilateralFilter(source, destination, 2 * radius_plane + 1, options.sigma_hu, sigma_plane,
                        cv::BORDER_REPLICATE);
  });
  const auto& size = volume.size();
  if (options.along_slices && size.nz > 1) {
    std::vector<float> spatial(static_cast<std::size_t>(2 * radius_k + 1));
    for (int t = -radius_k; t <= radius_k; ++t) {
      spatial[static_cast<std::size_t>(t + radius_k)] =
          static_cast<float>(std::exp(-0.5 * t * t / (sigma_k * sigma_k)));
    }
    const float range_scale = static_cast<float>(-0.5 / (options.sigma_hu * options.sigma_hu));
    filter_along_slices(volume, [&](const float* plane, std::int64_t j) {
      for (std::int64_t k = 0; k < size.nz; ++k) {
        const float* here = plane + k * size.nx;
        float* out = &volume.at(0, j, k);
        for (std::int64_t i = 0; i < size.nx; ++i) {
          float sum = 0, weight_sum = 0;
          for (int t = -radius_k; t <= radius_k; ++t) {
            const float value = plane[clamp_index(k + t, size.nz) * size.nx + i];
            const float d = value - here[i];
            const float w =
                spatial[static_cast<std::size_t>(t + radius_k)] * std::exp(range_scale * d * d);
            sum += w * value;
            weight_sum += w;
          }
          out[i] = sum / weight_sum;  // weight_sum ≥ 1: the centre tap has weight 1
        }
      }
    });
  }
  return {std::move(volume), std::move(record)};
}

}  // namespace typemerge::preprocess
