#include "preprocess/step_record.h"

#include <charconv>

namespace typemerge::preprocess {

const std::string* StepRecord::parameter(std::string_view key) const {
  for (const auto& [name, value] : parameters) {
    if (name == key) return &value;
  }
  return nullptr;
}

namespace detail {

std::string format_number(double value) {
  char buffer[32];
  const auto [end, error] = std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::general, 6);
  if (error != std::errc{}) return "?";
  return std::string(buffer, end);
}

std::string format_size(const core::VolumeSize& size) {
  return std::to_string(size.nx) + "×" + std::to_string(size.ny) + "×" + std::to_string(size.nz);
}

}  // namespace detail
}  // namespace typemerge::preprocess
