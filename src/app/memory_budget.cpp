#include "app/memory_budget.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace typemerge::app {

std::uint64_t conversion_memory_estimate(std::uint64_t voxels, const ConversionShape& shape) {
  const double surfaces = static_cast<double>(std::max<std::size_t>(shape.surfaces, 1));
  const double windows = static_cast<double>(shape.window_surfaces);
  const double volume_bytes = shape.int16_samples ? 2.0 : 4.0;
  const double per_voxel = volume_bytes + 2.0 * surfaces + 5.0 * windows +
                           surfaces * ((shape.reduces ? 4.0 : 0.0) + (shape.hollows ? 10.0 : 0.0));
  const double fixed_mib = 192.0 + 128.0 * (surfaces - 1.0) + 192.0 * windows +
                           surfaces * ((shape.reduces ? 192.0 : 0.0) +
                                       (shape.hollows ? 192.0 : 0.0));
  const double bytes = 1.1 * (static_cast<double>(voxels) * per_voxel + fixed_mib * (1 << 20));
  // Saturates instead of wrapping: an absurd grid is then simply over any budget.
  return bytes < 1.8e19 ? static_cast<std::uint64_t>(bytes) : std::uint64_t{1} << 63;
}

std::uint64_t working_voxels(const std::array<std::uint64_t, 3>& size,
                             const std::array<double, 3>& spacing_mm, double voxel_size_mm) {
  const std::uint64_t voxels = size[0] * size[1] * size[2];
  if (!(voxel_size_mm > 0)) return voxels;
  double resampled = 1;
  for (int k = 0; k < 3; ++k) {
    resampled *= std::ceil(static_cast<double>(size[k]) * spacing_mm[k] / voxel_size_mm) + 1;
  }
  // Saturates instead of wrapping: an absurd request is then simply over any budget.
  constexpr double kMax = 1e18;
  return voxels + static_cast<std::uint64_t>(std::min(resampled, kMax));
}

std::uint64_t default_memory_budget() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 4ull << 30;
  return std::uint64_t(pages) * std::uint64_t(page) / 4 * 3;
}

std::uint64_t parse_memory_size(const std::string& text) {
  const std::string message = "not a memory size: '" + text + "' (e.g. 512M, 8G)";
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    throw std::invalid_argument(message);
  }
  const std::string unit = text.substr(used);
  double scale = 1;
  if (unit == "K" || unit == "k") {
    scale = 1024.0;
  } else if (unit == "M" || unit == "m") {
    scale = 1024.0 * 1024;
  } else if (unit == "G" || unit == "g") {
    scale = 1024.0 * 1024 * 1024;
  } else if (unit == "T" || unit == "t") {
    scale = 1024.0 * 1024 * 1024 * 1024;
  } else if (!unit.empty()) {
    throw std::invalid_argument(message);
  }
  const double bytes = value * scale;
  if (!(bytes >= 1) || !std::isfinite(bytes) || bytes > 1.8e19) throw std::invalid_argument(message);
  return static_cast<std::uint64_t>(bytes);
}

std::string format_megabytes(std::uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.0f MiB", double(bytes) / (1 << 20));
  return text;
}

bool limit_address_space(std::uint64_t bytes) {
#if defined(__SANITIZE_ADDRESS__)
  (void)bytes;
  return false;
#else
  const rlimit limit{bytes, bytes};
  return ::setrlimit(RLIMIT_AS, &limit) == 0;
#endif
}

}  // namespace typemerge::app
