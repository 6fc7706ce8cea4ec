// The default series of a folder as the bench executables load it (convert's choice of series;
// --spacing resample as convert's --resample-spacing).
#pragma once

#include <cstdio>
#include <optional>
#include <string>

#include "core/volume.h"
#include "dicom/series_loader.h"

namespace typemerge::bench {

// The HU volume of the folder's default series, or nullopt (with a message on stderr) when the
// folder holds none. `resample_spacing`: accept uneven slice steps by resampling them.
inline std::optional<core::Volume> load_default_series(const std::string& dir,
                                                       bool resample_spacing) {
  dicom::ScanOptions scan_options;
  if (resample_spacing) scan_options.geometry.spacing = dicom::SpacingPolicy::resample;
  const auto scan = dicom::scan_folder(dir, scan_options);
  if (!scan.default_series) {
    std::fprintf(stderr, "no usable series in %s\n", dir.c_str());
    return std::nullopt;
  }
  return dicom::load_series(scan.series[*scan.default_series]).volume;
}

}  // namespace typemerge::bench
