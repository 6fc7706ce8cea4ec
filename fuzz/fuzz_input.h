// FuzzInput: reads typed values off the fuzzer's bytes, returning zeros once they run out, so
// every byte string decodes to some input and small mutations make small changes.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace typemerge::fuzz {

class FuzzInput {
 public:
  FuzzInput(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  std::uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }
  bool flag() { return (byte() & 1) != 0; }
  // 0 … count − 1.
  unsigned pick(unsigned count) { return count == 0 ? 0 : byte() % count; }

  template <typename T>
  T raw() {
    unsigned char bytes[sizeof(T)] = {};
    for (auto& b : bytes) b = byte();
    T value;
    std::memcpy(&value, bytes, sizeof value);
    return value;
  }

  // Any finite double (what the loader's strict DS parser lets through); NaN and infinities,
  // which it refuses, become 0.
  double finite_double() {
    const double value = raw<double>();
    return std::isfinite(value) ? value : 0.0;
  }

  bool empty() const { return at_ >= size_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

}  // namespace typemerge::fuzz
