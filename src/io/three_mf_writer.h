// write_3mf: meshes as one 3MF package (unit millimetre), the format slicers prefer to STL: it
// states its unit, shares vertices and holds several named, coloured parts. Written with lib3mf
// (Debian's lib3mf 1.8), atomically, and byte-reproducibly: the same parts give the same bytes.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace typemerge::io {

// One object of the package. Its name and colour also name and colour the base material the
// object carries (the 3MF core's way to colour an object, which slicers show).
struct ThreeMfPart {
  const core::TriangleMesh* mesh = nullptr;  // positions in mm, in the package's one frame
  std::string name;                          // a preset name: never patient data
  std::array<std::uint8_t, 3> srgb{};        // display colour
};

// The parts as objects in the given order, each placed by a build item with the identity
// transform, so they overlap where the tissues nest. `application` goes into the package's
// "Application" metadata (tool, version, space; never patient data); nothing else, no date.
// Throws std::runtime_error with lib3mf's message when the package cannot be built or written.
void write_3mf(const std::vector<ThreeMfPart>& parts, const std::filesystem::path& path,
               const std::string& application);

// Light grey: the colour of a surface that has no preset (iso, window, write_mesh).
inline constexpr std::array<std::uint8_t, 3> kSurfaceGrey = {0xC0, 0xC0, 0xC0};

// One grey object named "surface": what write_mesh writes for a .3mf path.
void write_3mf(const core::TriangleMesh& mesh, const std::filesystem::path& path,
               const std::string& application);

}  // namespace typemerge::io
