// Parsing of DICOM decimal strings (DS) and integer strings (IS), locale-free and strict.
//
// DCMTK's own DS conversion accepts "NaN" and "inf" and follows the C locale; a spacing of NaN
// or a comma-decimal locale must never reach the geometry, so the loader parses the raw text.
#pragma once

#include <optional>
#include <string_view>
#include <vector>

namespace typemerge::dicom {

// One DS value: optional surrounding spaces, then a finite decimal number. nullopt otherwise.
std::optional<double> parse_decimal(std::string_view text);

// A backslash-separated DS list with exactly `count` finite values; nullopt otherwise.
std::optional<std::vector<double>> parse_decimal_list(std::string_view text, std::size_t count);

std::optional<long long> parse_integer(std::string_view text);

}  // namespace typemerge::dicom
