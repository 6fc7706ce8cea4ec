// Mesh files besides binary STL: ASCII STL, PLY (binary little endian), OBJ and 3MF, chosen by
// the output's extension. All written atomically; coordinates as given (the caller maps spaces).
#pragma once

#include <filesystem>
#include <string>

#include "core/mesh.h"

namespace typemerge::io {

enum class MeshFormat { binary_stl, ascii_stl, ply, obj, three_mf };

// .stl → binary STL (ascii_stl only on request), .ply, .obj, .3mf; throws std::invalid_argument for
// other extensions.
MeshFormat mesh_format_for(const std::filesystem::path& path, bool ascii_stl);

// `comment` goes into the header/comment line (tool, version, space; never patient data).
void write_mesh(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                MeshFormat format, const std::string& comment);

}  // namespace typemerge::io
