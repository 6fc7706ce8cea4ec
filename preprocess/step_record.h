// StepRecord: what one preprocessing step did, as data for the CLI's report.
//
// Every step of typemerge::preprocess is a free function `StepResult f(volume, options)`; the
// record names the step, says in one sentence what it did with the numbers actually used
// (voxel sigmas, kernel sizes, index ranges), lists its parameters as key/value text and
// carries warnings. Nothing in this module prints.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/volume.h"

namespace typemerge::preprocess {

struct StepRecord {
  std::string step;         // machine name: "gaussian", "median", "bilateral", "resample", ...
  std::string description;  // one sentence with the effective numbers
  std::vector<std::pair<std::string, std::string>> parameters;  // key → value, in order
  std::vector<std::string> warnings;                            // e.g. "no tissue ≥ -400 HU"
  core::VolumeSize size_before;
  core::VolumeSize size_after;

  // The value of a parameter, or nullptr when the step did not record it.
  const std::string* parameter(std::string_view key) const;
};

struct StepResult {
  core::Volume volume;
  StepRecord record;
};

namespace detail {
// Six significant digits, no trailing zeros ("0.5", "0.897436", "1e-05", "-400").
std::string format_number(double value);
std::string format_size(const core::VolumeSize& size);  // "512×512×134"
}  // namespace detail

}  // namespace typemerge::preprocess
