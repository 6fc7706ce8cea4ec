#include "preprocess/consumed_input.h"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace typemerge::preprocess {

void ConsumedInput::consumed(std::size_t bytes) {
  // 2 MiB blocks: a volume's storage is on 2 MiB pages where the kernel grants them
  // (core::detail::allocate_samples), and fewer, larger calls cost less.
  constexpr std::uintptr_t kBlock = std::uintptr_t{2} << 20;
  if (bytes < released_ + kBlock) return;
#if defined(__linux__) && defined(MADV_DONTNEED)
  const auto base = reinterpret_cast<std::uintptr_t>(begin_);
  const std::uintptr_t from = (base + released_ + kBlock - 1) & ~(kBlock - 1);
  const std::uintptr_t to = (base + bytes) & ~(kBlock - 1);
  if (to <= from) return;
  ::madvise(reinterpret_cast<void*>(from), to - from, MADV_DONTNEED);
  released_ = to - base;
#endif
}

}  // namespace typemerge::preprocess
