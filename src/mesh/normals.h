// compute_vertex_normals: area-weighted vertex normals, for steps that move or replace
// vertices (smoothing, decimation) and so invalidate the extractor's gradient normals.
#pragma once

#include "core/mesh.h"

namespace typemerge::mesh {

// Sets mesh.normals (resized to positions.size()) to the normalised sum of the
// (area-weighted) cross products of the triangles around each vertex. A vertex used by no
// triangle, or whose sum vanishes, gets the zero normal ("unknown" in core::TriangleMesh).
void compute_vertex_normals(core::TriangleMesh& mesh);

}  // namespace typemerge::mesh
