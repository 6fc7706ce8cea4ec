#include "app/label_census.h"

#include <algorithm>
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

}  // namespace

std::map<std::int32_t, LabelExtent> label_census(const core::Volume& layer) {
  const auto& size = layer.size();
  float largest = 0;
  for (float v : layer.samples()) largest = std::max(largest, v);
  std::map<std::int32_t, LabelExtent> census;
  if (largest <= 65535.0f) {
    std::vector<LabelExtent> table(static_cast<std::size_t>(largest) + 1);
    for (std::int64_t k = 0; k < size.nz; ++k) {
      for (std::int64_t j = 0; j < size.ny; ++j) {
        const float* row = layer.slice(k) + j * size.nx;
        for (std::int64_t i = 0; i < size.nx; ++i) {
          if (row[i] > 0) add(table[static_cast<std::size_t>(row[i])], i, j, k);
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
      const float* row = layer.slice(k) + j * size.nx;
      for (std::int64_t i = 0; i < size.nx; ++i) {
        if (row[i] > 0) add(census[static_cast<std::int32_t>(row[i])], i, j, k);
      }
    }
  }
  return census;
}

}  // namespace typemerge::app
