// write_3mf: the mesh as a 3MF package (unit millimetre), the format slicers prefer to STL: it
// states its unit and shares vertices. Written with lib3mf (Debian's lib3mf 1.8), atomically.
#pragma once

#include <filesystem>
#include <string>

#include "core/mesh.h"

namespace typemerge::io {

// `name` becomes the object's name (a preset name: never patient data). Throws
// std::runtime_error with lib3mf's message when the package cannot be built or written.
void write_3mf(const core::TriangleMesh& mesh, const std::filesystem::path& path,
               const std::string& name);

}  // namespace typemerge::io
