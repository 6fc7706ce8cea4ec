// Names and colours of labels: read from a label table file, a fixed palette for the rest,
// and file names made safe and unique.
//
// Table formats, recognised line by line (blank lines and lines starting with # skipped):
//   index;name[;...]                          semicolon lines
//   index name R G B [A]                      3D Slicer .ctbl and FreeSurfer LUT (name one word)
//   index R G B A VIS MSH "name"              ITK-SNAP label description (name in quotes)
//   index name                                plain pairs
// Colours are 0..255 integers. A line that fits none is an error naming its line number.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace typemerge::app {

struct LabelName {
  std::string name;
  std::optional<std::array<std::uint8_t, 3>> srgb;
};

// Throws CommandError (usage) when the file cannot be read or a line fits no format.
std::map<std::int32_t, LabelName> read_label_names(const std::filesystem::path& path);
std::map<std::int32_t, LabelName> parse_label_names(const std::string& text);

// The n-th colour of a fixed palette of distinct colours (repeating after its length).
std::array<std::uint8_t, 3> palette_colour(std::size_t n);

// File stems for `names`, in order: characters outside [A-Za-z0-9._-] become '_', at most 64
// characters, no leading '.', empty → "label"; a stem already taken (ignoring case) gets
// "-2", "-3", ….
std::vector<std::string> safe_unique_stems(const std::vector<std::string>& names);

}  // namespace typemerge::app
