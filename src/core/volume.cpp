#include "volume.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "core/page_release.h"

namespace typemerge::core {

Vec3 IndexToPatient::apply(double i, double j, double k) const {
  Vec3 p = origin;
  for (int c = 0; c < 3; ++c) p[c] += i * axes[0][c] + j * axes[1][c] + k * axes[2][c];
  return p;
}

double IndexToPatient::determinant() const {
  const Vec3& a = axes[0];
  const Vec3& b = axes[1];
  const Vec3& c = axes[2];
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
}

std::array<Vec3, 3> IndexToPatient::cofactor_rows() const {
  auto cross = [](const Vec3& u, const Vec3& v) {
    return Vec3{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  };
  return {cross(axes[1], axes[2]), cross(axes[2], axes[0]), cross(axes[0], axes[1])};
}

double IndexToPatient::spacing(int axis) const {
  const Vec3& a = axes[axis];
  return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

Volume::Volume(VolumeSize size, IndexToPatient geometry)
    : size_(size), geometry_(geometry), samples_(static_cast<std::size_t>(size.voxels()), 0.0f) {}

Volume Volume::uninitialized(VolumeSize size, IndexToPatient geometry, SampleType type) {
  Volume volume;
  volume.size_ = size;
  volume.geometry_ = geometry;
  volume.type_ = type;
  // Default-initialised: the producer writes every sample.
  if (type == SampleType::int16) {
    volume.int16_.resize(static_cast<std::size_t>(size.voxels()));
  } else {
    volume.samples_.resize(static_cast<std::size_t>(size.voxels()));
  }
  return volume;
}

void Volume::to_float() {
  if (!holds_int16()) return;
  Samples values(int16_.size());
  std::copy(int16_.begin(), int16_.end(), values.begin());
  samples_ = std::move(values);
  int16_ = Int16Samples{};
  type_ = SampleType::float32;
}

bool Volume::to_int16_if_exact() {
  if (holds_int16()) return true;
  if (!std::all_of(samples_.begin(), samples_.end(),
                   [](float v) { return fits_int16(static_cast<double>(v)); })) {
    return false;
  }
  Int16Samples values(samples_.size());
  std::transform(samples_.begin(), samples_.end(), values.begin(),
                 [](float v) { return static_cast<std::int16_t>(v); });
  int16_ = std::move(values);
  samples_ = Samples{};
  type_ = SampleType::int16;
  return true;
}

void Volume::release_slices(std::int64_t begin, std::int64_t end) {
  begin = std::clamp<std::int64_t>(begin, 0, size_.nz);
  end = std::clamp<std::int64_t>(end, begin, size_.nz);
  const auto slice = static_cast<std::size_t>(size_.nx * size_.ny);
  const auto first = slice * static_cast<std::size_t>(begin);
  const auto samples = slice * static_cast<std::size_t>(end - begin);
  if (holds_int16()) {
    detail::release_whole_pages(int16_.data() + first, samples * sizeof(std::int16_t));
  } else {
    detail::release_whole_pages(samples_.data() + first, samples * sizeof(float));
  }
}

void Volume::throw_not_float() {
  throw std::logic_error("core::Volume: float samples asked of an int16 volume");
}

void Volume::throw_not_int16() {
  throw std::logic_error("core::Volume: int16 samples asked of a float volume");
}

}  // namespace typemerge::core
