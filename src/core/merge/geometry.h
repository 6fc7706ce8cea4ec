// The small vocabulary every pass of type merging shares: vertex and triangle ids, index-space
// points, boxes of cubes and which of a box's faces a point lies on, the 2D orientation test.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

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

// The area vector of triangle t (its normal, twice its area long), in index space.
inline P3 area_vector(std::span<const Position> positions, const Triangle& t) {
  const P3 p0 = to_double(positions[t[0]]);
  return cross(sub(to_double(positions[t[1]]), p0), sub(to_double(positions[t[2]]), p0));
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
// places a vertex on a lattice plane exactly, so equality is the test. With SSE2 the six
// comparisons are two vector ones (the same ordered equality as ==; a fourth lane of NaN
// equals nothing): mask() runs for every vertex of every box tested.
struct FaceTest {
  explicit FaceTest(const Box& box) {
    std::array<float, 3> lo;
    std::array<float, 3> hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = static_cast<float>(box.lo[a]);
      hi[a] = static_cast<float>(box.hi[a]);
    }
#if defined(__SSE2__)
    const float none = std::numeric_limits<float>::quiet_NaN();
    lo_ = _mm_setr_ps(lo[0], lo[1], lo[2], none);
    hi_ = _mm_setr_ps(hi[0], hi[1], hi[2], none);
#else
    lo_ = lo;
    hi_ = hi;
#endif
  }
  unsigned mask(const Position& p) const {
#if defined(__SSE2__)
    // p as the lanes (x, y, z, 0); each comparison's lane bits spread to the even bits.
    const __m128 xy = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(p.data()));
    const __m128 v = _mm_movelh_ps(xy, _mm_load_ss(&p[2]));
    static constexpr std::uint8_t kSpread[8] = {0, 1, 4, 5, 16, 17, 20, 21};
    const auto low = static_cast<unsigned>(_mm_movemask_ps(_mm_cmpeq_ps(v, lo_)));
    const auto high = static_cast<unsigned>(_mm_movemask_ps(_mm_cmpeq_ps(v, hi_)));
    return kSpread[low] | kSpread[high] << 1u;
#else
    return (p[0] == lo_[0] ? 1u : 0u) | (p[0] == hi_[0] ? 2u : 0u) | (p[1] == lo_[1] ? 4u : 0u) |
           (p[1] == hi_[1] ? 8u : 0u) | (p[2] == lo_[2] ? 16u : 0u) | (p[2] == hi_[2] ? 32u : 0u);
#endif
  }

 private:
#if defined(__SSE2__)
  __m128 lo_;
  __m128 hi_;
#else
  std::array<float, 3> lo_;
  std::array<float, 3> hi_;
#endif
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
