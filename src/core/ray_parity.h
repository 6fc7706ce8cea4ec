// Whether a point lies inside a closed surface: the parity of the crossings of the ray from it
// along a fixed, deliberately irrational direction (rays through edges and vertices of lattice
// meshes are then unlikely), each triangle tested by Möller & Trumbore (1997).
//
// Only a triangle whose shadow along the ray covers the point can be crossed, so RayParity
// buckets the triangles once by their shadows in a grid on the plane across the ray (about two
// triangles a cell, shadows widened by 1e-9 of the grid's extent against rounding in the
// projection): a query tests the triangles of its cell alone and counts exactly the crossings
// a test of every triangle counts. Memory: 4 bytes per cell (n / 2 cells) and per
// (triangle, cell) pair, plus 40 bytes a triangle while it is built.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh.h"

namespace typemerge::core {

// Does the ray from `origin` along RayParity's direction cross triangle (p0, p1, p2) at a
// distance > 0? (A ray in the triangle's plane crosses nothing.)
bool ray_crosses(const std::array<double, 3>& origin, const std::array<double, 3>& p0,
                 const std::array<double, 3>& p1, const std::array<double, 3>& p2);

class RayParity {
 public:
  // Over the triangles `ids` of `mesh` (e.g. one shell's), or over all of them. `mesh` must
  // outlive this and not change.
  RayParity(const TriangleMesh& mesh, std::span<const std::uint32_t> ids);
  explicit RayParity(const TriangleMesh& mesh);

  // Whether the ray from `point` crosses the triangles an odd number of times: inside, for a
  // closed surface and a point on none of its triangles.
  bool inside(const std::array<double, 3>& point) const;

 private:
  void build(std::span<const std::uint32_t> ids, bool all);

  const TriangleMesh& mesh_;
  double u0_ = 0, v0_ = 0, cell_ = 1;
  std::int64_t size_ = 0;             // cells per side (0: no triangles)
  std::vector<std::uint32_t> start_;  // cell → its triangles in triangles_ (CSR)
  std::vector<std::uint32_t> triangles_;
};

}  // namespace typemerge::core
