// Separable trilinear resampling, written by hand rather than with OpenCV:
//   - cv::resize aligns pixel edges (source = (dest + 0.5)·scale − 0.5) and takes its scale
//     from integer image sizes, so it would move the centre of voxel 0 and could not keep an
//     arbitrary voxel size exact;
//   - cv::remap quantises sample positions to 1/32 pixel (INTER_TAB_SIZE), which breaks the
//     exact reproduction of linear fields that the geometry tests rely on.
// Here each output slice is produced in two passes: blend the two input slices around its k
// position into a scratch slice, then for each output row blend two scratch rows and
// interpolate along i. Weights come from per-axis tables computed once in double.
#include "preprocess/resample.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "preprocess/consumed_input.h"

namespace typemerge::preprocess {
namespace {

using core::Volume;
using core::VolumeSize;

void assert_volume(const Volume& volume) {
  assert(volume.sample_bytes() ==
         static_cast<std::size_t>(volume.size().voxels()) * (volume.holds_int16() ? 2 : 4));
  for (int axis = 0; axis < 3; ++axis) assert(volume.geometry().spacing(axis) > 0);
  (void)volume;
}

bool positive(double value) { return std::isfinite(value) && value > 0; }

// Output position p' ↦ input position p'·step = low + weight, blending low and low + 1.
struct LinearTaps {
  std::vector<std::int64_t> low;
  std::vector<float> weight;  // of sample low + 1
};

LinearTaps linear_taps(std::int64_t input_count, std::int64_t output_count, double step) {
  LinearTaps taps;
  taps.low.resize(static_cast<std::size_t>(output_count));
  taps.weight.resize(static_cast<std::size_t>(output_count));
  for (std::int64_t p = 0; p < output_count; ++p) {
    const double position =
        std::min(static_cast<double>(p) * step, static_cast<double>(input_count - 1));
    const std::int64_t low =
        std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(position)), 0,
                                 std::max<std::int64_t>(input_count - 2, 0));
    taps.low[static_cast<std::size_t>(p)] = low;
    taps.weight[static_cast<std::size_t>(p)] =
        input_count > 1 ? static_cast<float>(position - static_cast<double>(low)) : 0.0f;
  }
  return taps;
}

// Largest count whose last sample stays within the input: floor((n − 1)/step) + 1, as a double
// so that a tiny step can be refused before it overflows. The small tolerance keeps
// 511·0.5/0.25 from losing its last sample to rounding.
double output_count(std::int64_t input_count, double step) {
  if (input_count <= 0) return 0;
  return std::floor(static_cast<double>(input_count - 1) / step + 1e-9) + 1;
}

// a + w·(b − a) over n samples, in float (an int16 sample is the float of its integer).
template <typename Sample>
void blend(const Sample* a, const Sample* b, float w, float* out, std::int64_t n) {
  if (w == 0.0f) {
    std::copy(a, a + n, out);
    return;
  }
  for (std::int64_t i = 0; i < n; ++i) {
    const float fa = a[i], fb = b[i];
    out[i] = fa + w * (fb - fa);
  }
}

// Resamples with index step `step` (old voxels per new voxel) along each axis.
// With `consume`, the input's storage is returned to the OS as its slices are read for the last
// time (ConsumedInput): the caller frees it afterwards and does not read it again.
StepResult resample_by_step(const Volume& volume, const double (&step)[3], const char* name,
                            std::int64_t max_output_voxels, bool consume = false) {
  assert_volume(volume);
  const VolumeSize& in = volume.size();
  const double counts[3] = {output_count(in.nx, step[0]), output_count(in.ny, step[1]),
                            output_count(in.nz, step[2])};
  if (counts[0] * counts[1] * counts[2] > static_cast<double>(max_output_voxels)) {
    throw std::invalid_argument(std::string(name) + ": output " + detail::format_number(counts[0]) +
                                "×" + detail::format_number(counts[1]) + "×" +
                                detail::format_number(counts[2]) + " exceeds max_output_voxels " +
                                std::to_string(max_output_voxels));
  }
  const VolumeSize out{static_cast<std::int64_t>(counts[0]), static_cast<std::int64_t>(counts[1]),
                       static_cast<std::int64_t>(counts[2])};
  core::IndexToPatient geometry = volume.geometry();  // origin kept: centre of voxel 0
  for (int axis = 0; axis < 3; ++axis) {
    for (double& c : geometry.axes[axis]) c *= step[axis];
  }
  StepResult result{Volume(out, geometry), {}};
  result.record.size_before = in;
  result.record.size_after = out;
  if (out.voxels() == 0) return result;

  const LinearTaps taps_i = linear_taps(in.nx, out.nx, step[0]);
  const LinearTaps taps_j = linear_taps(in.ny, out.ny, step[1]);
  const LinearTaps taps_k = linear_taps(in.nz, out.nz, step[2]);
  std::vector<float> slice(static_cast<std::size_t>(in.nx * in.ny));
  std::vector<float> row(static_cast<std::size_t>(in.nx));
  const std::int64_t k_high_limit = in.nz - 1;
  const std::int64_t j_high_limit = in.ny - 1;
  const std::size_t slice_bytes =
      static_cast<std::size_t>(in.nx * in.ny) * (volume.holds_int16() ? 2 : 4);
  ConsumedInput consumed(volume.visit([](const auto* samples) -> const void* { return samples; }));
  for (std::int64_t kp = 0; kp < out.nz; ++kp) {
    const std::int64_t k = taps_k.low[static_cast<std::size_t>(kp)];
    volume.visit([&](const auto* samples) {
      const auto n = in.nx * in.ny;
      blend(samples + k * n, samples + std::min(k + 1, k_high_limit) * n,
            taps_k.weight[static_cast<std::size_t>(kp)], slice.data(), n);
    });
    float* out_slice = result.volume.slice(kp);
    for (std::int64_t jp = 0; jp < out.ny; ++jp) {
      const std::int64_t j = taps_j.low[static_cast<std::size_t>(jp)];
      blend(slice.data() + j * in.nx, slice.data() + std::min(j + 1, j_high_limit) * in.nx,
            taps_j.weight[static_cast<std::size_t>(jp)], row.data(), in.nx);
      float* out_row = out_slice + jp * out.nx;
      for (std::int64_t ip = 0; ip < out.nx; ++ip) {
        const std::int64_t i = taps_i.low[static_cast<std::size_t>(ip)];
        const float w = taps_i.weight[static_cast<std::size_t>(ip)];
        const float a = row[static_cast<std::size_t>(i)];
        out_row[ip] = w == 0.0f ? a : a + w * (row[static_cast<std::size_t>(i + 1)] - a);
      }
    }
    // Output slices from kp + 1 on read input slices from their lowest tap on.
    if (consume && kp + 1 < out.nz) {
      consumed.consumed(static_cast<std::size_t>(taps_k.low[static_cast<std::size_t>(kp + 1)]) *
                        slice_bytes);
    }
  }
  return result;
}

std::string spacing_text(const core::IndexToPatient& geometry) {
  return detail::format_number(geometry.spacing(0)) + " × " +
         detail::format_number(geometry.spacing(1)) + " × " +
         detail::format_number(geometry.spacing(2)) + " mm";
}

void describe(StepRecord& record, const Volume& before, const Volume& after) {
  record.description += detail::format_size(record.size_before) + " at " +
                        spacing_text(before.geometry()) + " → " +
                        detail::format_size(record.size_after) + " at " +
                        spacing_text(after.geometry()) + ", trilinear, origin kept";
}

}  // namespace

namespace {

StepResult resample_impl(const Volume& volume, const ResampleOptions& options, bool consume) {
  for (int axis = 0; axis < 3; ++axis) {
    if (!positive(options.voxel_size_mm[axis])) {
      throw std::invalid_argument("resample: voxel_size_mm[" + std::to_string(axis) +
                                  "] must be > 0, got " +
                                  detail::format_number(options.voxel_size_mm[axis]));
    }
  }
  double step[3];
  for (int axis = 0; axis < 3; ++axis) {
    step[axis] = options.voxel_size_mm[axis] / volume.geometry().spacing(axis);
  }
  StepResult result =
      resample_by_step(volume, step, "resample", options.max_output_voxels, consume);
  result.record.step = "resample";
  result.record.parameters = {{"voxel_size_mm_i", detail::format_number(options.voxel_size_mm[0])},
                              {"voxel_size_mm_j", detail::format_number(options.voxel_size_mm[1])},
                              {"voxel_size_mm_k", detail::format_number(options.voxel_size_mm[2])},
                              {"interpolation", "linear"}};
  describe(result.record, volume, result.volume);
  return result;
}

StepResult isotropic_impl(const Volume& volume, const IsotropicOptions& options, bool consume) {
  if (!std::isfinite(options.voxel_size_mm) || options.voxel_size_mm < 0) {
    throw std::invalid_argument(
        std::string("resample_isotropic: voxel_size_mm must be ≥ 0 (0: smallest spacing), got ") +
        detail::format_number(options.voxel_size_mm));
  }
  assert_volume(volume);
  const core::IndexToPatient& geometry = volume.geometry();
  const double size =
      options.voxel_size_mm > 0
          ? options.voxel_size_mm
          : std::min({geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)});
  StepResult result =
      resample_impl(volume, {{size, size, size}, options.max_output_voxels}, consume);
  result.record.step = "resample_isotropic";
  result.record.parameters.insert(
      result.record.parameters.begin(),
      {"requested_voxel_size_mm", detail::format_number(options.voxel_size_mm)});
  result.record.description = std::string("isotropic ") + detail::format_number(size) + " mm: ";
  describe(result.record, volume, result.volume);
  return result;
}

}  // namespace

StepResult resample(const Volume& volume, const ResampleOptions& options) {
  return resample_impl(volume, options, false);
}

StepResult resample(Volume&& volume, const ResampleOptions& options) {
  StepResult result = resample_impl(volume, options, true);
  volume = Volume();
  return result;
}

StepResult resample_isotropic(const Volume& volume, const IsotropicOptions& options) {
  return isotropic_impl(volume, options, false);
}

StepResult resample_isotropic(Volume&& volume, const IsotropicOptions& options) {
  StepResult result = isotropic_impl(volume, options, true);
  volume = Volume();
  return result;
}

StepResult downsample(const Volume& volume, const DownsampleOptions& options) {
  if (options.factor < 1) {
    throw std::invalid_argument("downsample: factor must be ≥ 1, got " +
                                std::to_string(options.factor));
  }
  const double f = options.factor;
  const double step[3] = {f, f, f};
  StepResult result =
      resample_by_step(volume, step, "downsample", std::numeric_limits<std::int64_t>::max());
  result.record.step = "downsample";
  result.record.parameters = {{"factor", std::to_string(options.factor)}};
  result.record.description =
      std::string("preview, 1 voxel in ") + std::to_string(options.factor) + " per axis: ";
  describe(result.record, volume, result.volume);
  return result;
}

}  // namespace typemerge::preprocess
