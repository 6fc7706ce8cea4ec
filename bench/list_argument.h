// Comma-separated list arguments of the bench executables ("300,-500", "1,2").
#pragma once

#include <sstream>
#include <string>
#include <vector>

namespace typemerge::bench {

inline std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  std::string part;
  while (std::getline(stream, part, ',')) parts.push_back(part);
  return parts;
}

}  // namespace typemerge::bench
