// The small vocabulary every pass of type merging shares: vertex and triangle ids, index-space
// points, boxes of cubes and which of a box's faces a point lies on, the 2D orientation test.
#pragma once

#include <array>
#include <cstdint>
#include <limits>

namespace typemerge::core::merge {

using VertexId = std::uint32_t;
using Triangle = std::array<VertexId, 3>;
using Position = std::array<float, 3>;  // index space, as marching cubes places vertices
using P3 = std::array<double, 3>;
inline constexpr VertexId kNone = std::numeric_limits<VertexId>::max();

inline P3 to_double(const Position& p) { return {p[0], p[1], p[2]}; }
inline P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline double dot(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline P3 cross(const P3& a, const P3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// An index-space position in patient millimetres, up to the origin (`axes`: one index step
// in mm along each axis, IndexToPatient::axes): shapes are judged where the surface is printed.
inline P3 in_mm(const Position& p, const std::array<P3, 3>& axes) {
  P3 out{0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    for (int c = 0; c < 3; ++c) out[c] += static_cast<double>(p[a]) * axes[a][c];
  }
  return out;
}

// A block: cubes [lo, hi) along each axis (positions [lo, hi] in index space).
struct Box {
  std::array<std::int32_t, 3> lo;
  std::array<std::int32_t, 3> hi;
};
// A block's edges in cubes along x, y, z.
using Dims = std::array<std::int32_t, 3>;

inline bool one_cube(const Box& box) {
  return box.hi[0] - box.lo[0] == 1 && box.hi[1] - box.lo[1] == 1 && box.hi[2] - box.lo[2] == 1;
}

// Face bits of positions on a box: bit 2a (low face) and 2a + 1 (high face) of axis a, with
// the box's planes converted to float once (for the many vertices of one box). Marching cubes
// places a vertex on a lattice plane exactly, so equality is the test.
struct FaceTest {
  std::array<float, 3> lo;
  std::array<float, 3> hi;
  explicit FaceTest(const Box& box) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = static_cast<float>(box.lo[a]);
      hi[a] = static_cast<float>(box.hi[a]);
    }
  }
  unsigned mask(const Position& p) const {
    return (p[0] == lo[0] ? 1u : 0u) | (p[0] == hi[0] ? 2u : 0u) | (p[1] == lo[1] ? 4u : 0u) |
           (p[1] == hi[1] ? 8u : 0u) | (p[2] == lo[2] ? 16u : 0u) | (p[2] == hi[2] ? 32u : 0u);
  }
};

// Twice the signed area of the 2D triangle (a, b, c); > 0 when counter-clockwise.
inline double orient2d(const std::array<double, 2>& a, const std::array<double, 2>& b,
                       const std::array<double, 2>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

// Smallest twice-area (index units², in the projection) of a new triangle. Marching cubes'
// own triangles go down to about kEdgeMargin² (1e-6); new ones are kept at least that large,
// so they are no closer to degenerate in the written floats than marching cubes' (the tests
// count zero-area triangles in the files written from every real series).
inline constexpr double kMinDoubleArea = 1e-6;

}  // namespace typemerge::core::merge
