// Giving memory pages back to the operating system while keeping the buffer: for large
// buffers whose holder reads part of them no more (slices of a volume already extracted, a
// field's slices already used) or leaves them idle for a while (scratch between two uses).
#pragma once

#include <cstddef>

namespace typemerge::core::detail {

// Returns the whole pages inside [data, data + bytes) to the operating system: they read as
// zeros afterwards, and the process's resident memory shrinks by their size; the partial
// pages at the ends keep their contents. Linux (madvise MADV_DONTNEED); elsewhere nothing is
// released and the contents stay.
void release_whole_pages(void* data, std::size_t bytes) noexcept;

}  // namespace typemerge::core::detail
