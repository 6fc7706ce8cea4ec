// load_series: one scanned series → a Volume in Hounsfield units with its patient geometry.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/volume.h"
#include "dicom/series_scan.h"

namespace typemerge::dicom {

class LoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LoadOptions {
  std::uint64_t max_volume_bytes = std::uint64_t{16} << 30;  // refused before allocating
  // Store the samples as int16 when every value fits (integer rescale, no resampling, every
  // value within −32768…32767; core::Volume's int16 storage); false: always float.
  bool int16_samples = true;
};

struct LoadedSeries {
  core::Volume volume;                // HU, x fastest; geometry maps index → LPS mm; int16
                                      // or float samples (LoadOptions::int16_samples)
  std::string series_id;
  double tilt_degrees = 0;
  float min_hu = 0, max_hu = 0;
  std::vector<std::string> warnings;  // geometry, header and value warnings, in that order
};

// Whether load_series stores the series as int16 (before reading its pixels): integer
// rescale on every slice and no resampling. A value outside int16 found while decoding still
// makes it float.
bool loads_as_int16(const SeriesInfo& series, const LoadOptions& options = {});

// Throws LoadError with a one-line reason naming the series or file.
LoadedSeries load_series(const SeriesInfo& series, const LoadOptions& options = {});

// A warning when the values do not look like Hounsfield units (e.g. air near 0), else empty.
std::string hounsfield_plausibility_warning(float min_value, float max_value);

}  // namespace typemerge::dicom
