#include "app/label_names.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <fstream>
#include <set>
#include <sstream>

#include "app/exit_codes.h"

namespace typemerge::app {
namespace {

std::optional<long> to_int(const std::string& s) {
  long v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

std::optional<std::array<std::uint8_t, 3>> colour(const std::vector<std::string>& tokens,
                                                  std::size_t first) {
  if (tokens.size() < first + 3) return std::nullopt;
  std::array<std::uint8_t, 3> c{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto v = to_int(tokens[first + i]);
    if (!v || *v < 0 || *v > 255) return std::nullopt;
    c[i] = static_cast<std::uint8_t>(*v);
  }
  return c;
}

}  // namespace

std::map<std::int32_t, LabelName> parse_label_names(const std::string& text) {
  std::map<std::int32_t, LabelName> names;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  auto bad = [&] {
    return CommandError{kExitUsage, "--label-names: line " + std::to_string(number) +
                                        " is not 'index name R G B', 'index;name' or ITK-SNAP's "
                                        "'index R G B A VIS MSH \"name\"'"};
  };
  while (std::getline(in, line)) {
    ++number;
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;
    LabelName entry;
    std::optional<long> index;
    if (const auto semicolon = line.find(';'); semicolon != std::string::npos) {
      index = to_int(trim(line.substr(0, semicolon)));
      std::string rest = line.substr(semicolon + 1);
      entry.name = trim(rest.substr(0, rest.find(';')));
    } else if (const auto quote = line.find('"'); quote != std::string::npos) {
      const auto end = line.rfind('"');
      if (end == quote) throw bad();
      entry.name = line.substr(quote + 1, end - quote - 1);
      std::istringstream fields(line.substr(0, quote));
      std::vector<std::string> tokens;
      for (std::string t; fields >> t;) tokens.push_back(t);
      if (tokens.empty()) throw bad();
      index = to_int(tokens[0]);
      entry.srgb = colour(tokens, 1);
    } else {
      std::istringstream fields(line);
      std::vector<std::string> tokens;
      for (std::string t; fields >> t;) tokens.push_back(t);
      if (tokens.size() < 2) throw bad();
      index = to_int(tokens[0]);
      entry.name = tokens[1];
      entry.srgb = colour(tokens, 2);
    }
    if (!index || *index < 0 || *index > (1L << 24)) throw bad();
    if (*index == 0) continue;  // background
    names[static_cast<std::int32_t>(*index)] = entry;
  }
  return names;
}

std::map<std::int32_t, LabelName> read_label_names(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CommandError{kExitUsage, "--label-names: cannot read the file"};
  std::ostringstream text;
  text << in.rdbuf();
  return parse_label_names(text.str());
}

std::array<std::uint8_t, 3> palette_colour(std::size_t n) {
  // Twelve colours far apart in hue and lightness (ColorBrewer "Set3"-like, saturated a
  // little so printed parts differ).
  static constexpr std::array<std::array<std::uint8_t, 3>, 12> kPalette{{{230, 159, 0},
                                                                         {86, 180, 233},
                                                                         {0, 158, 115},
                                                                         {240, 228, 66},
                                                                         {0, 114, 178},
                                                                         {213, 94, 0},
                                                                         {204, 121, 167},
                                                                         {120, 94, 240},
                                                                         {150, 60, 60},
                                                                         {60, 150, 60},
                                                                         {200, 200, 200},
                                                                         {90, 90, 90}}};
  return kPalette[n % kPalette.size()];
}

std::vector<std::string> safe_unique_stems(const std::vector<std::string>& names) {
  std::vector<std::string> stems;
  std::set<std::string> taken;
  for (const std::string& name : names) {
    std::string stem;
    for (char c : name) {
      const bool ok =
          std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
      stem += ok ? c : '_';
      if (stem.size() >= 64) break;
    }
    while (!stem.empty() && stem.front() == '.') stem.erase(stem.begin());
    if (stem.empty()) stem = "label";
    auto key = [](std::string s) {
      std::transform(s.begin(), s.end(), s.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      return s;
    };
    std::string unique = stem;
    for (int n = 2; taken.count(key(unique)) > 0; ++n) unique = stem + "-" + std::to_string(n);
    taken.insert(key(unique));
    stems.push_back(unique);
  }
  return stems;
}

}  // namespace typemerge::app
