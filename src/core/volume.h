// Volume: a 3D scalar image in Hounsfield units with its exact place in patient space.
//
// The core works in voxel index space (i along a row, j down the columns, k across slices);
// one affine map takes an index to patient LPS millimetres. The map is general (not only
// rotation × spacing) because a gantry-tilted CT series is a sheared grid: its slice step is
// not parallel to the slice normal, and placing a surface exactly needs the shear, not a
// resampling.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace typemerge::core {

using Vec3 = std::array<double, 3>;

// index (i, j, k) → LPS mm:  origin + i·axes[0] + j·axes[1] + k·axes[2].
struct IndexToPatient {
  Vec3 origin{0, 0, 0};                                  // centre of voxel (0,0,0), mm
  std::array<Vec3, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};  // one index step, mm

  Vec3 apply(double i, double j, double k) const;
  // Determinant of [axes]: negative means the index frame is left-handed in LPS, so a
  // surface extracted in index space has to flip its winding to stay outward.
  double determinant() const;
  // The cofactor vectors axes[1]×axes[2], axes[2]×axes[0], axes[0]×axes[1]: the rows of
  // determinant() × the inverse of the linear part (the matrix with the axes as columns).
  std::array<Vec3, 3> cofactor_rows() const;
  double spacing(int axis) const;  // length of axes[axis]
};

struct VolumeSize {
  std::int64_t nx = 0;  // columns (i)
  std::int64_t ny = 0;  // rows (j)
  std::int64_t nz = 0;  // slices (k)
  std::int64_t voxels() const { return nx * ny * nz; }
  bool operator==(const VolumeSize&) const = default;
};

// An allocator whose new elements are left uninitialised (default-initialised), not zeroed:
// value-initialising a volume is a serial memset that also faults every page in on one thread,
// where the decoder threads write every sample anyway and fault their own pages in parallel.
// On 4 KiB pages, not huge ones (core/huge_pages.h): samples are read slice after slice, so
// huge pages save no TLB misses, and on virtual machines whose free memory goes back to the
// host a fresh 2 MiB page cost 3-5 times what its 4 KiB pages did (docs/benchmarks.md).
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  DefaultInitAllocator() = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

using Samples = std::vector<float, DefaultInitAllocator<float>>;
using Int16Samples = std::vector<std::int16_t, DefaultInitAllocator<std::int16_t>>;

// How a Volume stores its samples. int16 holds HU exactly as most CT series store them
// (integer rescale, values within −32768…32767) in half the memory of float; float holds
// everything else (non-integer rescale, interpolated, filtered or float inputs).
enum class SampleType : std::uint8_t { float32, int16 };

// Dense HU samples, x fastest, then y, then z (slice after slice), stored as float or int16
// (SampleType). Every reader sees float values: `at() const` and `visit` work for both
// storages, and an int16 sample reads as the float of the same integer, so arithmetic on the
// values is the same whichever storage holds them. The float views (`slice`, `samples`,
// `at` by reference) need float storage: they throw std::logic_error on an int16 volume
// (`to_float()` converts it first).
class Volume {
 public:
  Volume() = default;
  // Every sample 0, float storage.
  Volume(VolumeSize size, IndexToPatient geometry);
  // Samples left unset, for a producer that writes every one of them (the loader).
  static Volume uninitialized(VolumeSize size, IndexToPatient geometry,
                              SampleType type = SampleType::float32);

  const VolumeSize& size() const { return size_; }
  const IndexToPatient& geometry() const { return geometry_; }
  void set_geometry(const IndexToPatient& geometry) { geometry_ = geometry; }

  SampleType sample_type() const { return type_; }
  bool holds_int16() const { return type_ == SampleType::int16; }
  // Bytes the samples occupy (2 or 4 per voxel).
  std::size_t sample_bytes() const {
    return holds_int16() ? int16_.size() * sizeof(std::int16_t) : samples_.size() * sizeof(float);
  }

  // The value of a sample, whatever the storage.
  float at(std::int64_t i, std::int64_t j, std::int64_t k) const {
    const auto v = static_cast<std::size_t>(i + size_.nx * (j + size_.ny * k));
    return holds_int16() ? static_cast<float>(int16_[v]) : samples_[v];
  }
  // Float storage only.
  float& at(std::int64_t i, std::int64_t j, std::int64_t k) {
    return samples()[static_cast<std::size_t>(i + size_.nx * (j + size_.ny * k))];
  }
  // Float storage only.
  const float* slice(std::int64_t k) const {
    return samples().data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }
  float* slice(std::int64_t k) {
    return samples().data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }
  // Float storage only.
  const Samples& samples() const {
    if (holds_int16()) throw_not_float();
    return samples_;
  }
  Samples& samples() {
    if (holds_int16()) throw_not_float();
    return samples_;
  }
  // int16 storage only (std::logic_error otherwise).
  const Int16Samples& int16_samples() const {
    if (!holds_int16()) throw_not_int16();
    return int16_;
  }
  Int16Samples& int16_samples() {
    if (!holds_int16()) throw_not_int16();
    return int16_;
  }
  const std::int16_t* int16_slice(std::int64_t k) const {
    return int16_samples().data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }
  std::int16_t* int16_slice(std::int64_t k) {
    return int16_samples().data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }

  // Calls f(p) with p the first sample, `const float*` or `const std::int16_t*` as stored,
  // and returns what it returns: hot loops are written once as a template over the sample
  // type and instantiated for both.
  template <typename F>
  decltype(auto) visit(F&& f) const {
    if (holds_int16()) return f(static_cast<const std::int16_t*>(int16_.data()));
    return f(static_cast<const float*>(samples_.data()));
  }

  // Returns the memory pages wholly inside slices [begin, end) to the operating system, for a
  // holder that reads those slices no more (a conversion's last extraction, as it goes): they
  // read as 0 afterwards, and the process's resident memory shrinks by their size. Linux
  // (madvise MADV_DONTNEED); elsewhere nothing is released and the samples stay. Calls on
  // disjoint ranges may run at once.
  void release_slices(std::int64_t begin, std::int64_t end);

  // int16 → float storage, in place (the same values); nothing for float storage. Holds
  // both for a moment: 6 bytes a voxel.
  void to_float();
  // float → int16 storage when every sample is an integer in −32768…32767 (returns true;
  // also true for int16 storage already); otherwise unchanged, false.
  bool to_int16_if_exact();

 private:
  [[noreturn]] static void throw_not_float();
  [[noreturn]] static void throw_not_int16();

  VolumeSize size_;
  IndexToPatient geometry_;
  SampleType type_ = SampleType::float32;
  Samples samples_;
  Int16Samples int16_;
};

// True when `value` is an integer an int16 sample holds exactly (−0 is not: it would read
// back as +0).
inline bool fits_int16(double value) {
  return value >= -32768.0 && value <= 32767.0 &&
         value == static_cast<double>(static_cast<std::int32_t>(value)) &&
         !(value == 0.0 && std::signbit(value));
}

// The integer t with v >= iso exactly when v >= t, for every int16 v: ⌈iso⌉, clamped to
// −32768…32768 (32768: no sample is at or above iso; also for a NaN iso).
inline std::int32_t int16_threshold(float iso) {
  if (!(iso <= 32768.0f)) return 32768;
  if (iso < -32768.0f) return -32768;
  return static_cast<std::int32_t>(std::ceil(static_cast<double>(iso)));
}

}  // namespace typemerge::core
