// core::TriangleMesh ↔ OpenMesh TriMesh, the one place the two meet. Internal to
// typemerge::mesh (and its tests): nothing here may appear in a public header.
//
// OpenMesh's half-edge structure holds only manifold, consistently oriented surfaces, and its
// add_face refuses a face that would break that (and prints why). to_openmesh therefore
// prepares the input so that add_face never has to refuse:
//  1. triangles with a repeated index are skipped;
//  2. a triangle is rejected when one of its directed edges is already used by an earlier
//     triangle (a flipped neighbour, or a third face on an edge) or its undirected edge
//     already has two triangles — first come, first kept;
//  3. a vertex whose remaining triangles form several fans (two shells touching at a
//     vertex, as the extractor may produce) gets one copy per extra fan.
// Every accepted triangle is added with its winding, so orientation is preserved.
#pragma once

#include <cstddef>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "core/mesh.h"

namespace typemerge::mesh::detail {

struct OpenMeshTraits : public OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using OpenMeshTriMesh = OpenMesh::TriMesh_ArrayKernelT<OpenMeshTraits>;

struct ToOpenMesh {
  OpenMeshTriMesh mesh;
  std::size_t skipped_repeated_index = 0;  // step 1
  std::size_t rejected_faces = 0;          // step 2, plus any add_face still refused
  std::size_t split_vertices = 0;          // step 3: copies added
};

// Vertices keep their index (unused ones included); the copies of step 3 follow them.
ToOpenMesh to_openmesh(const core::TriangleMesh& mesh);

// Live (not deleted) vertices and faces in handle order; vertex normals are recomputed
// (area-weighted). Does not need garbage_collection first.
core::TriangleMesh from_openmesh(const OpenMeshTriMesh& mesh);

}  // namespace typemerge::mesh::detail
