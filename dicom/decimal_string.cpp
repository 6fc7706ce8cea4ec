#include "dicom/decimal_string.h"

#include <charconv>
#include <cmath>

namespace typemerge::dicom {
namespace {

std::string_view trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\0')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.remove_suffix(1);
  return text;
}

}  // namespace

std::optional<double> parse_decimal(std::string_view text) {
  text = trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);  // DS allows a leading '+'
  if (text.empty()) return std::nullopt;
  // from_chars accepts "nan" and "inf"; DS does not, so only digits, sign, point and exponent.
  for (char c : text) {
    const bool allowed = (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.' || c == 'e' ||
                         c == 'E';
    if (!allowed) return std::nullopt;
  }
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::optional<std::vector<double>> parse_decimal_list(std::string_view text, std::size_t count) {
  std::vector<double> values;
  while (true) {
    const std::size_t split = text.find('\\');
    const auto value = parse_decimal(text.substr(0, split));
    if (!value) return std::nullopt;
    values.push_back(*value);
    if (split == std::string_view::npos) break;
    text.remove_prefix(split + 1);
  }
  if (values.size() != count) return std::nullopt;
  return values;
}

std::optional<long long> parse_integer(std::string_view text) {
  text = trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  long long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace typemerge::dicom
