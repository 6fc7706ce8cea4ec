// A minimal NIfTI-1 reader for comparing the loader with dcm2niix (an independent reference).
// Reads single-file .nii with the data types dcm2niix writes for CT; values are returned
// scaled by scl_slope/scl_inter, x fastest.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <vector>

namespace typemerge::test {

struct NiftiImage {
  std::array<std::int64_t, 3> dims{};
  std::array<double, 3> pixdim{};
  std::vector<double> values;
  double at(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return values[static_cast<std::size_t>(i + dims[0] * (j + dims[1] * k))];
  }
};

inline NiftiImage read_nifti(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 352) throw std::runtime_error("short NIfTI file " + path.string());
  auto get = [&](std::size_t offset, auto value) {
    std::memcpy(&value, bytes.data() + offset, sizeof value);
    return value;
  };
  NiftiImage image;
  for (int d = 0; d < 3; ++d) {
    image.dims[d] = get(42 + 2 * d, std::int16_t{});
    image.pixdim[d] = get(80 + 4 * d, float{});
  }
  const auto datatype = get(70, std::int16_t{});
  const auto offset = static_cast<std::size_t>(get(108, float{}));
  double slope = get(112, float{});
  const double intercept = get(116, float{});
  if (slope == 0) slope = 1;
  const std::size_t count = static_cast<std::size_t>(image.dims[0] * image.dims[1] * image.dims[2]);
  image.values.resize(count);
  for (std::size_t v = 0; v < count; ++v) {
    double raw = 0;
    switch (datatype) {
      case 2: raw = get(offset + v, std::uint8_t{}); break;
      case 4: raw = get(offset + 2 * v, std::int16_t{}); break;
      case 512: raw = get(offset + 2 * v, std::uint16_t{}); break;
      case 8: raw = get(offset + 4 * v, std::int32_t{}); break;
      case 16: raw = get(offset + 4 * v, float{}); break;
      default: throw std::runtime_error("unsupported NIfTI datatype");
    }
    image.values[v] = raw * slope + intercept;
  }
  return image;
}

}  // namespace typemerge::test
