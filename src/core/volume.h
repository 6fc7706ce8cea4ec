// Volume: a 3D scalar image in Hounsfield units with its exact place in patient space.
//
// The core works in voxel index space (i along a row, j down the columns, k across slices);
// one affine map takes an index to patient LPS millimetres. The map is general (not only
// rotation × spacing) because a gantry-tilted CT series is a sheared grid: its slice step is
// not parallel to the slice normal, and placing a surface exactly needs the shear, not a
// resampling.
#pragma once

#include <array>
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
  double spacing(int axis) const;  // length of axes[axis]
};

struct VolumeSize {
  std::int64_t nx = 0;  // columns (i)
  std::int64_t ny = 0;  // rows (j)
  std::int64_t nz = 0;  // slices (k)
  std::int64_t voxels() const { return nx * ny * nz; }
  bool operator==(const VolumeSize&) const = default;
};

namespace detail {
// Storage of at least kHugeBuffer bytes is aligned to 2 MiB and, on Linux, advised for
// transparent huge pages (madvise(MADV_HUGEPAGE), what the kernel's default "madvise" mode
// waits for): a volume of 4 KiB pages is faulted in 4 KiB at a time, 77 k faults for 300 MiB,
// a visible share of a conversion's CPU; with 2 MiB pages, 150 (the perf figure:
// docs/benchmarks.md, "Moved from headers and the README"). Smaller storage comes from
// operator new.
inline constexpr std::size_t kHugeBuffer = std::size_t{8} << 20;
void* allocate_samples(std::size_t bytes);
void deallocate_samples(void* p, std::size_t bytes) noexcept;
}  // namespace detail

// An allocator whose new elements are left uninitialised (default-initialised), not zeroed:
// value-initialising a volume is a serial memset that also faults every page in on one thread,
// where the decoder threads write every sample anyway and fault their own pages in parallel.
// Large storage is on huge pages (detail::allocate_samples).
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  using value_type = T;
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(detail::allocate_samples(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept { detail::deallocate_samples(p, n * sizeof(T)); }
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

// Dense HU samples, x fastest, then y, then z (slice after slice).
class Volume {
 public:
  Volume() = default;
  // Every sample 0.
  Volume(VolumeSize size, IndexToPatient geometry);
  // Samples left unset, for a producer that writes every one of them (the loader).
  static Volume uninitialized(VolumeSize size, IndexToPatient geometry);

  const VolumeSize& size() const { return size_; }
  const IndexToPatient& geometry() const { return geometry_; }
  void set_geometry(const IndexToPatient& geometry) { geometry_ = geometry; }

  float at(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return samples_[static_cast<std::size_t>(i + size_.nx * (j + size_.ny * k))];
  }
  float& at(std::int64_t i, std::int64_t j, std::int64_t k) {
    return samples_[static_cast<std::size_t>(i + size_.nx * (j + size_.ny * k))];
  }
  const float* slice(std::int64_t k) const {
    return samples_.data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }
  float* slice(std::int64_t k) {
    return samples_.data() + static_cast<std::size_t>(size_.nx * size_.ny * k);
  }
  const Samples& samples() const { return samples_; }
  Samples& samples() { return samples_; }

 private:
  VolumeSize size_;
  IndexToPatient geometry_;
  Samples samples_;
};

}  // namespace typemerge::core
