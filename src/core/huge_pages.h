// Transparent huge pages for large arrays. Under the kernel's default "madvise" mode a buffer
// is faulted in 4 KiB at a time unless advised, and on virtual machines a fault costs
// microseconds: an extraction writes its large arrays once, so their faults are a visible
// share of its time (docs/benchmarks.md, "Huge pages for the core's arrays"). Advice only:
// where the kernel refuses it, 4 KiB pages as before.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace typemerge::core::detail {

// Buffers below this many bytes are left to operator new as they are (their pages are few,
// and a partly used 2 MiB page costs more memory than their faults cost time).
inline constexpr std::size_t kHugeBuffer = std::size_t{2} << 20;

// At least kHugeBuffer bytes: aligned to 2 MiB and advised for huge pages
// (madvise(MADV_HUGEPAGE) on Linux); less: operator new. Pages are mapped as they are first
// written, 2 MiB at a time, so at most the last, partly written page costs memory beyond what
// is written. deallocate_on_huge_pages takes the same byte count back.
void* allocate_on_huge_pages(std::size_t bytes);
void deallocate_on_huge_pages(void* p, std::size_t bytes) noexcept;

// A standard allocator on allocate_on_huge_pages: for the large arrays an extraction writes
// once and reads back (std::vector<T, HugePageAllocator<T>>).
template <typename T>
struct HugePageAllocator {
  using value_type = T;
  HugePageAllocator() = default;
  template <typename U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) { return static_cast<T*>(allocate_on_huge_pages(n * sizeof(T))); }
  void deallocate(T* p, std::size_t n) noexcept { deallocate_on_huge_pages(p, n * sizeof(T)); }
  template <typename U>
  bool operator==(const HugePageAllocator<U>&) const noexcept {
    return true;
  }
};

template <typename T>
using HugePageVector = std::vector<T, HugePageAllocator<T>>;

// Advises the whole 2 MiB pages inside [data, data + bytes) (nothing below kHugeBuffer), for
// buffers another allocator made. Pages already mapped stay as they are; the partial pages
// at the ends keep 4 KiB pages.
void advise_huge_pages(const void* data, std::size_t bytes) noexcept;

// v.reserve(n), then the advice for v's whole capacity.
template <typename Vector>
void reserve_on_huge_pages(Vector& v, std::size_t n) {
  v.reserve(n);
  advise_huge_pages(v.data(), v.capacity() * sizeof(typename Vector::value_type));
}

}  // namespace typemerge::core::detail
