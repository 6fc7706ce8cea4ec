// TriangleMesh: the indexed triangle surface the core produces, and the one map that takes it
// from voxel index space to patient LPS millimetres.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/volume.h"

namespace typemerge::core {

// An indexed triangle mesh. positions[i] and normals[i] describe vertex i (normals are unit
// length, or zero when unknown); triangles index into positions and are wound so that the
// right-hand rule gives the outward side. Units are those of the producer: the extractor
// writes voxel index space, to_patient converts to LPS mm.
struct TriangleMesh {
  std::vector<std::array<float, 3>> positions;
  std::vector<std::array<float, 3>> normals;
  std::vector<std::array<std::uint32_t, 3>> triangles;

  bool empty() const { return triangles.empty(); }
};

// Maps positions with `geometry` (index → LPS mm) and normals with the inverse transpose of
// its linear part (renormalised), so gradient normals stay perpendicular to the surface
// under shear and anisotropic spacing. When the map reverses orientation (determinant < 0)
// every triangle's winding is flipped so that it still faces outward.
// Precondition: geometry.determinant() != 0.
void to_patient(TriangleMesh& mesh, const IndexToPatient& geometry);

// (p1 − p0) × (p2 − p0) of a triangle, in double: its length is twice the area and its
// direction the outward normal for an outward-wound triangle. The one place every area,
// facet normal and degeneracy test of the project is computed.
std::array<double, 3> triangle_area_vector(const TriangleMesh& mesh,
                                           const std::array<std::uint32_t, 3>& triangle);

// Removes vertices no triangle uses (and their normals), renumbering the triangles and keeping
// the others in their order; returns how many were removed. Precondition: every index <
// mesh.positions.size().
std::size_t remove_unreferenced_vertices(TriangleMesh& mesh);

// Axis-aligned bounds of the vertex positions; min > max (empty) for a mesh without vertices.
struct BoundingBox {
  std::array<double, 3> min{1e300, 1e300, 1e300};
  std::array<double, 3> max{-1e300, -1e300, -1e300};
};
BoundingBox bounding_box(const TriangleMesh& mesh);

// The unit facet normal, or (0, 0, 0) for a zero-area triangle.
std::array<double, 3> facet_normal(const TriangleMesh& mesh,
                                   const std::array<std::uint32_t, 3>& triangle);

}  // namespace typemerge::core
