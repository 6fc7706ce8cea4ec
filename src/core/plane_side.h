// A triangle's plane for many side tests: the statically filtered orientation that the
// crossing tests (self_intersections.cpp) and the bounded collapses' crossing filter share.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "core/mesh.h"

namespace typemerge::core {

// Which side of triangle (a, b, c)'s plane a point is on, when double arithmetic decides it
// for certain: the sign of det[p − a, b − a, c − a] = (p − a)·((b − a) × (c − a)), expanded
// along p − a so the cross product and its absolute terms are computed once per triangle and
// each point costs two dot products. The bound is Shewchuk's o3derrboundA (Adaptive precision
// floating-point arithmetic, 1997): the same rounded differences, products and sums as his
// orient3d, with the matrix transposed. Undecided cases (near or on the plane) are left to
// exact predicates, which would cost several times more for every pair.
struct PlaneSide {
  PlaneSide(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& t)
      : origin(mesh.positions[t[0]]) {
    const auto& b = mesh.positions[t[1]];
    const auto& c = mesh.positions[t[2]];
    const double e1[3] = {double{b[0]} - origin[0], double{b[1]} - origin[1],
                          double{b[2]} - origin[2]};
    const double e2[3] = {double{c[0]} - origin[0], double{c[1]} - origin[1],
                          double{c[2]} - origin[2]};
    for (int k = 0; k < 3; ++k) {
      const int i = (k + 1) % 3;
      const int j = (k + 2) % 3;
      normal[k] = e1[i] * e2[j] - e1[j] * e2[i];
      magnitude[k] = std::abs(e1[i] * e2[j]) + std::abs(e1[j] * e2[i]);
    }
  }
  // +1 or −1 when certain, 0 when not.
  int side(const std::array<float, 3>& p) const {
    const double q[3] = {double{p[0]} - origin[0], double{p[1]} - origin[1],
                         double{p[2]} - origin[2]};
    const double det = q[0] * normal[0] + q[1] * normal[1] + q[2] * normal[2];
    const double permanent = std::abs(q[0]) * magnitude[0] + std::abs(q[1]) * magnitude[1] +
                             std::abs(q[2]) * magnitude[2];
    constexpr double kBound = (7.0 + 56.0 * 0x1p-53) * 0x1p-53;
    if (det > kBound * permanent) return 1;
    if (-det > kBound * permanent) return -1;
    return 0;
  }
  // True when every listed vertex is certainly strictly on one side: then none of what they
  // span meets the triangle.
  template <std::size_t N>
  bool one_side(const TriangleMesh& mesh, const std::array<std::uint32_t, N>& points) const {
    const int first = side(mesh.positions[points[0]]);
    if (first == 0) return false;
    for (std::size_t i = 1; i < N; ++i) {
      if (side(mesh.positions[points[i]]) != first) return false;
    }
    return true;
  }

  // True when the corners of `other` that are not corners of `own` (this plane's triangle)
  // exist and are certainly strictly on one side: then every point of `other` but the shared
  // corners is off the plane, so the two cannot count as crossing (self_intersections.h: no
  // common point, none besides the shared vertex, or no overlap along the shared edge).
  bool separates(const TriangleMesh& mesh, const std::array<std::uint32_t, 3>& own,
                 const std::array<std::uint32_t, 3>& other) const {
    int first = 0;
    for (auto w : other) {
      if (w == own[0] || w == own[1] || w == own[2]) continue;
      const int side_of = side(mesh.positions[w]);
      if (side_of == 0 || (first != 0 && side_of != first)) return false;
      first = side_of;
    }
    return first != 0;
  }

  std::array<float, 3> origin;
  double normal[3];
  double magnitude[3];
};

}  // namespace typemerge::core
