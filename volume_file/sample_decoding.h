// Typed samples (the integer and float types NIfTI and NRRD store) decoded to the float samples
// of a core::Volume, with byte order and a linear scale — or to int16 samples when the scaled
// values are integers within int16 (fits_int16), as a CT series usually stores them.
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

// True when every value slope · raw + inter of these samples is an integer an int16 holds
// (core::fits_int16), so that the int16 decode_samples below gives the float one's values
// exactly: an integer type, slope 1 and an integer intercept, with the values in range —
// decided by the type's range (int8, uint8; int16 with intercept 0) or else by a pass over
// the data. Float types and other scales: false. Same preconditions as decode_samples.
bool fits_int16(std::span<const std::uint8_t> data, SampleType type, bool swap, std::size_t first,
                std::size_t stride, std::size_t count, double slope, double inter);

// fits_int16's answer where the type and scale decide it (true: every value of the type fits;
// false: a float type or another scale), std::nullopt where the data decides.
std::optional<bool> int16_by_type(SampleType type, double slope, double inter);

// out[v] = raw[first + v · stride] + inter as int16, the summary as the float decode gives it.
// Precondition: fits_int16 with the same arguments (asserted).
DecodeSummary decode_samples(std::span<const std::uint8_t> data, SampleType type, bool swap,
                             std::size_t first, std::size_t stride, std::size_t count, double slope,
                             double inter, std::int16_t* out);

}  // namespace typemerge::volume_file
