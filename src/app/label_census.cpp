#include "app/label_census.h"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace typemerge::app {
namespace {

void add(LabelExtent& e, std::int64_t i, std::int64_t j, std::int64_t k) {
  if (e.voxels++ == 0) {
    e.min = e.max = {i, j, k};
    return;
  }
  e.min = {std::min(e.min[0], i), std::min(e.min[1], j), std::min(e.min[2], k)};
  e.max = {std::max(e.max[0], i), std::max(e.max[1], j), std::max(e.max[2], k)};
}

// Over the samples as stored (float or int16: core::Volume::visit), read as floats.
template <typename Sample>
std::map<std::int32_t, LabelExtent> census_of(const Sample* samples, const core::VolumeSize& size) {
  float largest = 0;
  for (std::int64_t v = 0; v < size.voxels(); ++v) {
    largest = std::max(largest, static_cast<float>(samples[v]));
  }
  std::map<std::int32_t, LabelExtent> census;
  if (largest <= 65535.0f) {
    std::vector<LabelExtent> table(static_cast<std::size_t>(largest) + 1);
    for (std::int64_t k = 0; k < size.nz; ++k) {
      for (std::int64_t j = 0; j < size.ny; ++j) {
        const Sample* row = samples + (k * size.ny + j) * size.nx;
        for (std::int64_t i = 0; i < size.nx; ++i) {
          if (row[i] > 0) add(table[static_cast<std::size_t>(static_cast<float>(row[i]))], i, j, k);
        }
      }
    }
    for (std::size_t label = 1; label < table.size(); ++label) {
      if (table[label].voxels > 0) census[static_cast<std::int32_t>(label)] = table[label];
    }
    return census;
  }
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      const Sample* row = samples + (k * size.ny + j) * size.nx;
      for (std::int64_t i = 0; i < size.nx; ++i) {
        if (row[i] > 0) add(census[static_cast<std::int32_t>(static_cast<float>(row[i]))], i, j, k);
      }
    }
  }
  return census;
}

template <typename Sample>
double coherence_of(const Sample* samples, const core::VolumeSize& size) {
  std::uint64_t counted = 0;
  std::uint64_t same = 0;
  for (std::int64_t r = 0; r < size.ny * size.nz; ++r) {
    const Sample* row = samples + r * size.nx;
    for (std::int64_t i = 0; i + 1 < size.nx; ++i) {
      if (row[i] > 0) {
        ++counted;
        if (row[i + 1] == row[i]) ++same;
      }
    }
  }
  return counted == 0 ? 1.0 : static_cast<double>(same) / static_cast<double>(counted);
}

}  // namespace

std::map<std::int32_t, LabelExtent> label_census(const core::Volume& layer) {
  return layer.visit([&](const auto* samples) { return census_of(samples, layer.size()); });
}

double label_coherence(const core::Volume& layer) {
  return layer.visit([&](const auto* samples) { return coherence_of(samples, layer.size()); });
}

}  // namespace typemerge::app
