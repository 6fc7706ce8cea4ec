#include "volume_file/sample_decoding.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

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

// The least and greatest raw value, as doubles (exact for every value that can fit int16).
template <typename T>
std::pair<double, double> raw_range(const std::uint8_t* data, bool swap, std::size_t first,
                                    std::size_t stride, std::size_t count) {
  T lo = std::numeric_limits<T>::max(), hi = std::numeric_limits<T>::lowest();
  for (std::size_t v = 0; v < count; ++v) {
    const T raw = load<T>(data + (first + v * stride) * sizeof(T), swap);
    lo = std::min(lo, raw);
    hi = std::max(hi, raw);
  }
  return {static_cast<double>(lo), static_cast<double>(hi)};
}

template <typename T>
DecodeSummary decode_int16(const std::uint8_t* data, bool swap, std::size_t first,
                           std::size_t stride, std::size_t count, std::int32_t inter,
                           std::int16_t* out) {
  DecodeSummary summary;
  std::int32_t lo = std::numeric_limits<std::int32_t>::max(), hi = -lo;
  for (std::size_t v = 0; v < count; ++v) {
    const T raw = load<T>(data + (first + v * stride) * sizeof(T), swap);
    const auto value = static_cast<std::int32_t>(static_cast<std::int64_t>(raw) + inter);
    assert(value >= -32768 && value <= 32767);
    lo = std::min(lo, value);
    hi = std::max(hi, value);
    out[v] = static_cast<std::int16_t>(value);
  }
  if (count > 0) {
    summary.min = static_cast<float>(lo);
    summary.max = static_cast<float>(hi);
  }
  return summary;
}

// Calls f(T{}) with T the C++ type of an integer SampleType; false for float types.
template <typename F>
bool with_integer_type(SampleType type, F f) {
  switch (type) {
    case SampleType::int8:
      f(std::int8_t{});
      return true;
    case SampleType::uint8:
      f(std::uint8_t{});
      return true;
    case SampleType::int16:
      f(std::int16_t{});
      return true;
    case SampleType::uint16:
      f(std::uint16_t{});
      return true;
    case SampleType::int32:
      f(std::int32_t{});
      return true;
    case SampleType::uint32:
      f(std::uint32_t{});
      return true;
    case SampleType::int64:
      f(std::int64_t{});
      return true;
    case SampleType::uint64:
      f(std::uint64_t{});
      return true;
    case SampleType::float32:
    case SampleType::float64:
      break;
  }
  return false;
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

namespace typemerge::volume_file {

std::optional<bool> int16_by_type(SampleType type, double slope, double inter) {
  // raw + inter for integer raw is exact in double; an intercept beyond ±65535 never fits.
  if (slope != 1.0 || !(std::abs(inter) <= 65535.0) || inter != std::floor(inter)) return false;
  std::optional<bool> decided = false;  // float types
  with_integer_type(type, [&](auto zero) {
    using T = decltype(zero);
    if (static_cast<double>(std::numeric_limits<T>::lowest()) + inter >= -32768.0 &&
        static_cast<double>(std::numeric_limits<T>::max()) + inter <= 32767.0) {
      decided = true;
    } else {
      decided = std::nullopt;  // the data decides
    }
  });
  return decided;
}

bool fits_int16(std::span<const std::uint8_t> data, SampleType type, bool swap, std::size_t first,
                std::size_t stride, std::size_t count, double slope, double inter) {
  assert(stride >= 1);
  assert(count == 0 || (first + (count - 1) * stride + 1) * sample_bytes(type) <= data.size());
  const std::optional<bool> decided = int16_by_type(type, slope, inter);
  if (decided.has_value()) return *decided;
  if (count == 0) return true;
  bool fits = false;
  with_integer_type(type, [&](auto zero) {
    using T = decltype(zero);
    const auto [lo, hi] = raw_range<T>(data.data(), swap, first, stride, count);
    fits = lo + inter >= -32768.0 && hi + inter <= 32767.0;
  });
  return fits;
}

DecodeSummary decode_samples(std::span<const std::uint8_t> data, SampleType type, bool swap,
                             std::size_t first, std::size_t stride, std::size_t count, double slope,
                             double inter, std::int16_t* out) {
  assert(fits_int16(data, type, swap, first, stride, count, slope, inter));
  (void)slope;
  DecodeSummary summary;
  with_integer_type(type, [&](auto zero) {
    using T = decltype(zero);
    summary = decode_int16<T>(data.data(), swap, first, stride, count,
                              static_cast<std::int32_t>(inter), out);
  });
  return summary;
}

}  // namespace typemerge::volume_file
