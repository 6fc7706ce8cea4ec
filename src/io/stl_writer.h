// Binary STL: 80-byte header, triangle count, 50 bytes per triangle (84 + 50·n bytes).
//
// The header names the tool, its version and the coordinate space ("SPACE=LPS", as 3D Slicer
// writes it) and never anything from the input's patient data. Written atomically.
#pragma once

#include <filesystem>
#include <string>

#include "core/mesh.h"

namespace typemerge::io {

// The 80-byte header text: "typemerge <version> SPACE=<space>", space-padded.
std::string stl_header(const std::string& version, const std::string& space);

// Facet normals are computed from the winding (slicers ignore stored normals, but some
// validators compare them). Throws std::runtime_error; no partial file is left behind.
void write_binary_stl(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                      const std::string& header);

// Reads a binary or ASCII STL and welds corners with identical coordinates into shared
// vertices, so that topology checks see the surface's connectivity.
core::TriangleMesh read_stl(const std::filesystem::path& path);

}  // namespace typemerge::io
