#include "dicom/series_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <type_traits>
#include <utility>

#include <tbb/parallel_for.h>

#include "dicom/pixel_reader.h"

namespace typemerge::dicom {
namespace {

// Decodes every acquired slice into `stack` (one slice per ordered header), file by file, so
// a multi-frame file is decoded once; Sample is float or std::int16_t (then NotInt16 is
// thrown for a value outside it).
// Returns the lowest and highest value decoded, which the decoder finds as it writes them (a
// serial std::minmax_element afterwards was a fifth of the loader's time; a second pass per
// file, 4 % of a bone conversion's CPU under -O2, perf).
template <typename Sample>
std::pair<float, float> decode_stack(const SeriesInfo& series, Sample* stack,
                                     std::size_t slice_voxels) {
  std::map<std::filesystem::path, std::vector<FrameTarget>> by_file;
  for (std::size_t k = 0; k < series.slices.size(); ++k) {
    Sample* target = stack + k * slice_voxels;
    if constexpr (std::is_same_v<Sample, float>) {
      by_file[series.slices[k].path].push_back({&series.slices[k], target});
    } else {
      by_file[series.slices[k].path].push_back({&series.slices[k], nullptr, target});
    }
  }
  // Files are independent and each writes its own slices, so they decode in parallel; DCMTK's
  // decoders keep no shared state once registered. The first error (in file order) is thrown,
  // so the message does not depend on scheduling.
  std::vector<const std::vector<FrameTarget>*> files;
  for (const auto& entry : by_file) files.push_back(&entry.second);
  std::vector<std::string> errors(files.size());
  std::vector<char> not_int16(files.size(), 0);
  std::vector<std::pair<float, float>> ranges(files.size());
  tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t f) {
    try {
      ranges[f] = read_frames_hu(*files[f]);
    } catch (const NotInt16&) {
      not_int16[f] = 1;
    } catch (const PixelError& error) {
      errors[f] = error.what();
    }
  });
  for (const std::string& error : errors) {
    if (!error.empty()) throw PixelError(error);
  }
  if (std::find(not_int16.begin(), not_int16.end(), 1) != not_int16.end()) {
    throw NotInt16("a value outside int16");
  }
  if (ranges.empty()) return {0.0f, 0.0f};
  std::pair<float, float> range = ranges.front();
  for (const auto& [lowest, highest] : ranges) {
    range.first = std::min(range.first, lowest);
    range.second = std::max(range.second, highest);
  }
  return range;
}

// Integer RescaleSlope and RescaleIntercept on every slice (of a size the int32 arithmetic of
// a stored value cannot overflow): every value is an integer, most likely within int16.
bool integer_rescale(const SeriesInfo& series) {
  return std::all_of(series.slices.begin(), series.slices.end(), [](const SliceHeader& s) {
    return std::abs(s.rescale_slope) <= 65536.0 && std::abs(s.rescale_intercept) <= 65536.0 &&
           s.rescale_slope == std::trunc(s.rescale_slope) &&
           s.rescale_intercept == std::trunc(s.rescale_intercept);
  });
}

// Linear resampling along the slice line onto the uniform grid the geometry chose.
void resample_stack(const core::Samples& stack, const StackGeometry& geometry,
                    std::size_t slice_voxels, core::Volume& volume) {
  const auto& offsets = geometry.normal_offsets;
  std::size_t upper = 1;
  for (std::int64_t k = 0; k < geometry.output_slices; ++k) {
    const double at = offsets.front() + static_cast<double>(k) * geometry.slice_step_mm;
    while (upper + 1 < offsets.size() && offsets[upper] < at) ++upper;
    const double span = offsets[upper] - offsets[upper - 1];
    const double t = std::clamp((at - offsets[upper - 1]) / span, 0.0, 1.0);
    const float* a = stack.data() + (upper - 1) * slice_voxels;
    const float* b = stack.data() + upper * slice_voxels;
    float* out = volume.slice(k);
    const auto weight = static_cast<float>(t);
    for (std::size_t p = 0; p < slice_voxels; ++p) out[p] = a[p] + weight * (b[p] - a[p]);
  }
}

}  // namespace

std::string hounsfield_plausibility_warning(float min_value, float max_value) {
  // Every CT volume of a body holds some air (around −1000 HU) outside or in the airways;
  // data whose darkest value is far above it was most likely not rescaled to HU.
  if (min_value <= -500.0f) return {};
  char text[200];
  std::snprintf(text, sizeof text,
                "values range from %.0f to %.0f: no air near -1000 HU, so these may not be "
                "Hounsfield units and HU presets would not fit",
                static_cast<double>(min_value), static_cast<double>(max_value));
  return text;
}

bool loads_as_int16(const SeriesInfo& series, const LoadOptions& options) {
  return options.int16_samples && !series.geometry.needs_resampling && integer_rescale(series);
}

LoadedSeries load_series(const SeriesInfo& series, const LoadOptions& options) {
  if (series.role != SeriesRole::volume) {
    throw LoadError("series " + series.id + " is a localizer (" + series.role_reason +
                    "), not a volume");
  }
  if (!series.geometry.ok()) {
    throw LoadError("series " + series.id + " refused: " + series.geometry.error);
  }
  const StackGeometry& geometry = series.geometry;
  const core::VolumeSize size{series.columns, series.rows, geometry.output_slices};
  const std::size_t slice_voxels = std::size_t{series.columns} * series.rows;
  const std::uint64_t acquired_bytes = std::uint64_t{slice_voxels} * series.slices.size() * 4;
  // In double: a resampled grid of 65535² × 2^31 voxels would wrap a 64-bit byte count.
  const double grid_bytes = static_cast<double>(size.voxels()) * 4;
  const double needed_bytes =
      grid_bytes + (geometry.needs_resampling ? static_cast<double>(acquired_bytes) : 0);
  const std::uint64_t needed = needed_bytes >= 0x1p63 ? std::uint64_t{1} << 63
                                                      : static_cast<std::uint64_t>(needed_bytes);
  if (needed_bytes > static_cast<double>(options.max_volume_bytes)) {
    throw LoadError("series " + series.id + " needs " + std::to_string(needed >> 20) +
                    " MiB, above the limit of " + std::to_string(options.max_volume_bytes >> 20) +
                    " MiB");
  }

  LoadedSeries loaded;
  loaded.series_id = series.id;
  loaded.tilt_degrees = geometry.tilt_degrees;
  loaded.warnings = geometry.warnings;
  loaded.warnings.insert(loaded.warnings.end(), series.warnings.begin(), series.warnings.end());
  // int16 samples when every value is an integer in int16's range: decided from the rescale
  // of the headers, confirmed by the values (one outside int16 decodes the series again, into
  // floats). Resampled slices are interpolated, so not integers: floats.
  const bool int16 = loads_as_int16(series, options);
  std::pair<float, float> range;
  try {
    bool decoded = false;
    if (int16) {
      // Every sample is written by the decoders.
      loaded.volume = core::Volume::uninitialized(size, geometry.index_to_patient,
                                                  core::SampleType::int16);
      try {
        range = decode_stack(series, loaded.volume.int16_samples().data(), slice_voxels);
        decoded = true;
      } catch (const NotInt16&) {
        loaded.volume = core::Volume{};
      }
    }
    if (decoded) {
    } else if (geometry.needs_resampling) {
      // Every sample is written by the resampling of every slice.
      loaded.volume = core::Volume::uninitialized(size, geometry.index_to_patient);
      core::Samples stack(slice_voxels * series.slices.size());
      decode_stack(series, stack.data(), slice_voxels);
      resample_stack(stack, geometry, slice_voxels, loaded.volume);
      // The grid's values, not the acquired ones (interpolation stays within them, but a
      // grid slice need not meet the extreme voxel).
      const auto [lowest, highest] =
          std::minmax_element(loaded.volume.samples().begin(), loaded.volume.samples().end());
      range = {*lowest, *highest};
    } else {
      loaded.volume = core::Volume::uninitialized(size, geometry.index_to_patient);
      range = decode_stack(series, loaded.volume.samples().data(), slice_voxels);
    }
  } catch (const PixelError& error) {
    throw LoadError("series " + series.id + ": " + error.what());
  }

  const bool missing_rescale = std::any_of(series.slices.begin(), series.slices.end(),
                                           [](const SliceHeader& s) { return !s.has_rescale; });
  if (missing_rescale) {
    loaded.warnings.emplace_back("no RescaleSlope/RescaleIntercept: stored values used as they are");
  }
  loaded.min_hu = range.first;
  loaded.max_hu = range.second;
  if (auto warning = hounsfield_plausibility_warning(loaded.min_hu, loaded.max_hu);
      !warning.empty()) {
    loaded.warnings.push_back(std::move(warning));
  }
  return loaded;
}

}  // namespace typemerge::dicom
