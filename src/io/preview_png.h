// A shaded PNG preview of a mesh, so a person can check a batch of outputs by looking.
//
// Two orthographic views side by side: anterior (the patient's face, patient's left on the
// viewer's right, head up) and left lateral. A z-buffered software rasteriser: no display,
// no GPU and no VTK needed on a server; OpenCV holds the image, libpng encodes it.
#pragma once

#include <filesystem>

#include "core/mesh.h"

namespace typemerge::io {

struct PreviewOptions {
  int view_pixels = 512;  // each view is view_pixels × view_pixels
};

// Mesh in patient LPS mm. Atomic write; throws std::runtime_error.
void write_preview_png(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                       const PreviewOptions& options = {});

}  // namespace typemerge::io
