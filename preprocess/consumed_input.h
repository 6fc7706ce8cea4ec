// ConsumedInput: returns the storage of an input that a step reads once, front to back, to the
// OS as the step reads it, so that the step's peak is its output rather than input + output.
//
// Contract: after consumed(n), the first n bytes from `begin` may read as zeros (Linux:
// madvise(MADV_DONTNEED) on the whole 2 MiB blocks among them; elsewhere nothing happens).
// The caller owns the input and only frees it afterwards; it must not read those bytes again.
// The storage stays allocated (its address range is kept), only its pages go.
#pragma once

#include <cstddef>

namespace typemerge::preprocess {

class ConsumedInput {
 public:
  explicit ConsumedInput(const void* begin) : begin_(begin) {}
  // The first `bytes` bytes are read for the last time (`bytes` may only grow).
  void consumed(std::size_t bytes);
  // Bytes from `begin` up to the end of the last block returned (0 where nothing is).
  std::size_t released_bytes() const { return released_; }

 private:
  const void* begin_;
  std::size_t released_ = 0;
};

}  // namespace typemerge::preprocess
