#include "volume_file/sample_decoding.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>

namespace typemerge::volume_file {
namespace {

template <typename T>
T load(const std::uint8_t* p, bool swap) {
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if (swap) std::reverse(bytes, bytes + sizeof(T));
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

template <typename T>
DecodeSummary decode(const std::uint8_t* data, bool swap, std::size_t first, std::size_t stride,
                     std::size_t count, double slope, double inter, float* out) {
  DecodeSummary summary;
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  const bool identity = slope == 1.0 && inter == 0.0;
  for (std::size_t v = 0; v < count; ++v) {
    const T raw = load<T>(data + (first + v * stride) * sizeof(T), swap);
    double value = static_cast<double>(raw);
    if (!identity) value = slope * value + inter;
    // A double beyond float's range does not convert (undefined), so it counts as non-finite.
    float f = 0;
    if (std::isfinite(value) && std::abs(value) <= double(std::numeric_limits<float>::max())) {
      f = static_cast<float>(value);
    } else {
      ++summary.non_finite;
    }
    if (f != std::nearbyint(f)) summary.all_integer = false;
    lo = std::min(lo, f);
    hi = std::max(hi, f);
    out[v] = f;
  }
  if (count > 0) {
    summary.min = lo;
    summary.max = hi;
  }
  return summary;
}

}  // namespace

std::size_t sample_bytes(SampleType type) {
  switch (type) {
    case SampleType::int8:
    case SampleType::uint8:
      return 1;
    case SampleType::int16:
    case SampleType::uint16:
      return 2;
    case SampleType::int32:
    case SampleType::uint32:
    case SampleType::float32:
      return 4;
    case SampleType::int64:
    case SampleType::uint64:
    case SampleType::float64:
      return 8;
  }
  return 1;
}

bool is_integer(SampleType type) {
  return type != SampleType::float32 && type != SampleType::float64;
}

std::string_view to_string(SampleType type) {
  switch (type) {
    case SampleType::int8:
      return "int8";
    case SampleType::uint8:
      return "uint8";
    case SampleType::int16:
      return "int16";
    case SampleType::uint16:
      return "uint16";
    case SampleType::int32:
      return "int32";
    case SampleType::uint32:
      return "uint32";
    case SampleType::int64:
      return "int64";
    case SampleType::uint64:
      return "uint64";
    case SampleType::float32:
      return "float32";
    case SampleType::float64:
      return "float64";
  }
  return "?";
}

DecodeSummary decode_samples(std::span<const std::uint8_t> data, SampleType type, bool swap,
                             std::size_t first, std::size_t stride, std::size_t count, double slope,
                             double inter, float* out) {
  assert(stride >= 1);
  assert(count == 0 || (first + (count - 1) * stride + 1) * sample_bytes(type) <= data.size());
  const std::uint8_t* p = data.data();
  switch (type) {
    case SampleType::int8:
      return decode<std::int8_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::uint8:
      return decode<std::uint8_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::int16:
      return decode<std::int16_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::uint16:
      return decode<std::uint16_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::int32:
      return decode<std::int32_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::uint32:
      return decode<std::uint32_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::int64:
      return decode<std::int64_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::uint64:
      return decode<std::uint64_t>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::float32:
      return decode<float>(p, swap, first, stride, count, slope, inter, out);
    case SampleType::float64:
      return decode<double>(p, swap, first, stride, count, slope, inter, out);
  }
  return {};
}

}  // namespace typemerge::volume_file
