// Typed samples (the integer and float types NIfTI and NRRD store) decoded to the float samples
// of a core::Volume, with byte order and a linear scale.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace typemerge::volume_file {

enum class SampleType {
  int8,
  uint8,
  int16,
  uint16,
  int32,
  uint32,
  int64,
  uint64,
  float32,
  float64
};

std::size_t sample_bytes(SampleType type);
bool is_integer(SampleType type);
std::string_view to_string(SampleType type);

struct DecodeSummary {
  std::size_t non_finite = 0;  // NaN or infinite samples (after scaling), stored as 0
  bool all_integer = true;     // every stored value an integer
  float min = 0, max = 0;      // of the stored values (0, 0 when there are none)
};

// out[v] = slope · raw[first + v · stride] + inter for v in [0, count), where raw is `data`
// read as `type` (byte-swapped when `swap`). Preconditions: stride ≥ 1 and `data` holds at
// least (first + (count − 1) · stride + 1) samples. Integers above 2^24 round to the nearest
// float; non-finite results are stored as 0 and counted.
DecodeSummary decode_samples(std::span<const std::uint8_t> data, SampleType type, bool swap,
                             std::size_t first, std::size_t stride, std::size_t count, double slope,
                             double inter, float* out);

}  // namespace typemerge::volume_file
