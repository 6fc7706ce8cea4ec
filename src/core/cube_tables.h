// Marching-cubes tables: the numbering of the cube's vertices, edges and faces, and the
// per-configuration triangulations built by the face-loop construction.
//
// Provenance: the numbering is the Lorensen–Cline / VTK cube (vtkMarchingCubes,
// vtkHexahedron) as pinned in type-merging-spec.md §1.1–1.2; it differs from the widely
// copied Bourke/Bloyd tables only in that e10 and e11 are swapped. The triangulations are
// not typed in: `triangulate_cube` derives them from the cube index and one decision per
// ambiguous face (spec §5.3, the loop construction of the prototype tm/sim.py), and the
// case tables below are that function evaluated at compile time. To change a table, change
// the construction; there is nothing to regenerate by hand.
//
//                 v3 ------------ e2 ------------ v2
//                /|                              /|
//             e10 |                           e11 |
//              /  e3                           /  e1          y (T)
//            v7 ------------ e6 ------------ v6   |           |
//             |   |                           |   |           +--- x (R)
//             |   v0 ------------ e0 ---------|-- v1         /
//            e7  /                           e5  /          z (F, toward the viewer)
//             | e8                            | e9
//             |/                              |/
//            v4 ------------ e4 ------------ v5
//
//   v0..v7 = (0,0,0) (1,0,0) (1,1,0) (0,1,0) (0,0,1) (1,0,1) (1,1,1) (0,1,1)
//   e0..e11 = v0v1 v1v2 v3v2 v0v3 v4v5 v5v6 v7v6 v4v7 v0v4 v1v5 v3v7 v2v6
//             (every edge is listed from its lower to its upper endpoint)
//   faces f = 2·axis + side: f0 = x-low (L), f1 = x-high (R), f2 = y-low (D), f3 = y-high (T),
//             f4 = z-low (B), f5 = z-high (F)
//
// Cube index: bit i is set when vertex vi is inside (state 1, value >= iso).
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>

namespace typemerge::core {

inline constexpr int kCubeVertexCount = 8;
inline constexpr int kCubeEdgeCount = 12;
inline constexpr int kCubeFaceCount = 6;

// Lattice offset (x, y, z) of each cube vertex.
inline constexpr std::array<std::array<int, 3>, kCubeVertexCount> kCubeVertexOffset{
    {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}};

// The one canonical table: endpoints of each edge, lower endpoint first. Everything else
// about edges is derived from it and from kCubeVertexOffset.
inline constexpr std::array<std::array<int, 2>, kCubeEdgeCount> kCubeEdgeVertices{{{0, 1},
                                                                                   {1, 2},
                                                                                   {3, 2},
                                                                                   {0, 3},
                                                                                   {4, 5},
                                                                                   {5, 6},
                                                                                   {7, 6},
                                                                                   {4, 7},
                                                                                   {0, 4},
                                                                                   {1, 5},
                                                                                   {3, 7},
                                                                                   {2, 6}}};

namespace detail {

constexpr int edge_axis(int edge) {
  const auto& a = kCubeVertexOffset[kCubeEdgeVertices[edge][0]];
  const auto& b = kCubeVertexOffset[kCubeEdgeVertices[edge][1]];
  for (int axis = 0; axis < 3; ++axis) {
    if (a[axis] != b[axis]) return axis;
  }
  return -1;
}

constexpr int vertex_at(int x, int y, int z) {
  for (int v = 0; v < kCubeVertexCount; ++v) {
    const auto& o = kCubeVertexOffset[v];
    if (o[0] == x && o[1] == y && o[2] == z) return v;
  }
  return -1;
}

constexpr int edge_between(int a, int b) {
  for (int e = 0; e < kCubeEdgeCount; ++e) {
    const auto& ends = kCubeEdgeVertices[e];
    if ((ends[0] == a && ends[1] == b) || (ends[0] == b && ends[1] == a)) return e;
  }
  return -1;
}

}  // namespace detail

// The lattice edge a cube edge lies on: cube (i,j,k) edge e is the lattice edge that starts at
// (i,j,k) + offset and runs one step along `axis`. This key is what neighbouring cubes share.
struct LatticeEdge {
  std::array<int, 3> offset;
  int axis;
};

inline constexpr std::array<LatticeEdge, kCubeEdgeCount> kCubeEdgeLattice = [] {
  std::array<LatticeEdge, kCubeEdgeCount> table{};
  for (int e = 0; e < kCubeEdgeCount; ++e) {
    table[e] = {kCubeVertexOffset[kCubeEdgeVertices[e][0]], detail::edge_axis(e)};
  }
  return table;
}();

// Vertices of each face in counter-clockwise order seen from outside the cube, i.e. the
// right-hand rule around the cycle gives the outward face normal. For the face with normal
// +axis the cycle runs (0,0) (1,0) (1,1) (0,1) in the coordinates (u, w) = (axis+1, axis+2)
// mod 3, a right-handed pair; the face with normal −axis runs the other way round.
inline constexpr std::array<std::array<int, 4>, kCubeFaceCount> kCubeFaceVertices = [] {
  std::array<std::array<int, 4>, kCubeFaceCount> table{};
  constexpr int kHighCycle[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  constexpr int kLowCycle[4][2] = {{0, 0}, {0, 1}, {1, 1}, {1, 0}};
  for (int f = 0; f < kCubeFaceCount; ++f) {
    const int axis = f / 2;
    const int side = f % 2;
    const int u = (axis + 1) % 3;
    const int w = (axis + 2) % 3;
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> p{};
      p[axis] = side;
      p[u] = side ? kHighCycle[k][0] : kLowCycle[k][0];
      p[w] = side ? kHighCycle[k][1] : kLowCycle[k][1];
      table[f][k] = detail::vertex_at(p[0], p[1], p[2]);
    }
  }
  return table;
}();

// Edge k of a face joins its vertices k and k+1 (mod 4).
inline constexpr std::array<std::array<int, 4>, kCubeFaceCount> kCubeFaceEdges = [] {
  std::array<std::array<int, 4>, kCubeFaceCount> table{};
  for (int f = 0; f < kCubeFaceCount; ++f) {
    for (int k = 0; k < 4; ++k) {
      table[f][k] =
          detail::edge_between(kCubeFaceVertices[f][k], kCubeFaceVertices[f][(k + 1) % 4]);
    }
  }
  return table;
}();

// Bit f is set when edge e lies in face f (every edge lies in exactly two faces).
inline constexpr std::array<std::uint8_t, kCubeEdgeCount> kCubeEdgeFaceMask = [] {
  std::array<std::uint8_t, kCubeEdgeCount> table{};
  for (int f = 0; f < kCubeFaceCount; ++f) {
    for (int e : kCubeFaceEdges[f]) table[e] = static_cast<std::uint8_t>(table[e] | (1u << f));
  }
  return table;
}();

// Bit e is set when edge e joins an inside and an outside vertex.
inline constexpr std::array<std::uint16_t, 256> kCubeCutEdges = [] {
  std::array<std::uint16_t, 256> table{};
  for (unsigned c = 0; c < 256; ++c) {
    for (int e = 0; e < kCubeEdgeCount; ++e) {
      const unsigned a = (c >> kCubeEdgeVertices[e][0]) & 1u;
      const unsigned b = (c >> kCubeEdgeVertices[e][1]) & 1u;
      if (a != b) table[c] = static_cast<std::uint16_t>(table[c] | (1u << e));
    }
  }
  return table;
}();

// A face is ambiguous when its corner states alternate around it (diagonal corners equal,
// adjacent corners different): the contour on it can either join the two inside corners or
// separate them, and the states alone do not say which. Bit f is set for each such face.
inline constexpr std::array<std::uint8_t, 256> kCubeAmbiguousFaces = [] {
  std::array<std::uint8_t, 256> table{};
  for (unsigned c = 0; c < 256; ++c) {
    for (int f = 0; f < kCubeFaceCount; ++f) {
      unsigned s[4];
      for (int k = 0; k < 4; ++k) s[k] = (c >> kCubeFaceVertices[f][k]) & 1u;
      if (s[0] == s[2] && s[1] == s[3] && s[0] != s[1]) {
        table[c] = static_cast<std::uint8_t>(table[c] | (1u << f));
      }
    }
  }
  return table;
}();

// ---- The face-loop construction --------------------------------------------------------------

// Most triangles one cube can produce: every triangle of a loop's fan or centre fan can be
// charged to a distinct loop vertex, and a cube has at most 12 surface vertices.
inline constexpr int kMaxCaseTriangles = 12;
// A loop needs a centre vertex only if it has at least 4 vertices, so at most 12 / 4.
inline constexpr int kMaxCaseCentroids = 3;
// Local vertex ids in a CubeCase: 0..11 are the surface vertices on the cube's edges,
// kFirstCentroid + k is the centre vertex of the k-th loop that needed one.
inline constexpr std::uint8_t kFirstCentroid = 12;

// The triangulation of one cube for one set of face decisions.
struct CubeCase {
  std::uint8_t triangle_count = 0;
  std::uint8_t centroid_count = 0;
  std::uint8_t loop_count = 0;  // the loops (one connected piece each)
  // Edges whose surface vertices are averaged into centre vertex k (bit e = edge e).
  std::array<std::uint16_t, kMaxCaseCentroids> centroid_edges{};
  // Local vertex ids, wound so that the right-hand rule points from inside to outside.
  std::array<std::array<std::uint8_t, 3>, kMaxCaseTriangles> triangles{};

  constexpr bool operator==(const CubeCase&) const = default;
};

// Triangulates cube index `index` (bit i = vertex vi inside).
//
// `joined_faces` bit f says, for an ambiguous face f, that the contour joins the face's two
// inside corners (the saddle of the bilinear interpolant is inside); otherwise they are cut
// off separately. Bits of non-ambiguous faces are ignored.
//
// Construction (spec §5.3):
//  1. Each face contributes its contour segments. Walking the face's vertex cycle (CCW seen
//     from outside), a segment runs from a crossing where the walk enters the inside to the
//     crossing where it leaves it; so the outside lies to the segment's left and, once the
//     segments are closed into loops, the right-hand rule around a loop points outward.
//     Neighbouring cubes walk a shared face in opposite directions, so they emit the same
//     segment with opposite orientation, which is what makes the surface closed and
//     consistently oriented.
//  2. Every cut edge starts exactly one segment and ends exactly one, so the segments chain
//     into closed loops; a loop is started at its lowest-numbered edge.
//  3. Each loop is fanned from the first vertex whose diagonals avoid all cube faces: a
//     diagonal inside a face could also be drawn by the neighbour across that face and the
//     edge would then belong to more than two triangles. When no such apex exists the loop
//     gets a centre vertex and a fan around it.
constexpr CubeCase triangulate_cube(unsigned index, unsigned joined_faces) {
  // next[e] = the edge whose vertex follows e's vertex around its loop.
  std::array<int, kCubeEdgeCount> next{};
  for (int& n : next) n = -1;

  for (int f = 0; f < kCubeFaceCount; ++f) {
    // Crossings in walk order: edge, and whether the walk enters the inside there.
    int cross_edge[4] = {};
    bool cross_enters[4] = {};
    int count = 0;
    for (int k = 0; k < 4; ++k) {
      const unsigned a = (index >> kCubeFaceVertices[f][k]) & 1u;
      const unsigned b = (index >> kCubeFaceVertices[f][(k + 1) % 4]) & 1u;
      if (a != b) {
        cross_edge[count] = kCubeFaceEdges[f][k];
        cross_enters[count] = b == 1u;
        ++count;
      }
    }
    if (count == 2) {
      const int enter = cross_enters[0] ? 0 : 1;
      next[cross_edge[enter]] = cross_edge[1 - enter];
    } else if (count == 4) {
      // Crossings alternate enter/leave. Separated inside corners: each entering crossing is
      // followed by the next crossing in walk order (the segment cuts off the inside corner
      // between them). Joined: by the previous one (the segment cuts off an outside corner).
      const bool joined = ((joined_faces >> f) & 1u) != 0;
      for (int k = 0; k < 4; ++k) {
        if (!cross_enters[k]) continue;
        next[cross_edge[k]] = cross_edge[joined ? (k + 3) % 4 : (k + 1) % 4];
      }
    }
  }

  CubeCase result{};
  unsigned visited = 0;
  for (int start = 0; start < kCubeEdgeCount; ++start) {
    if (next[start] < 0 || ((visited >> start) & 1u) != 0) continue;
    ++result.loop_count;
    int loop[kCubeEdgeCount] = {};
    int n = 0;
    for (int e = start; ((visited >> e) & 1u) == 0; e = next[e]) {
      visited |= 1u << e;
      loop[n++] = e;
    }

    int apex = -1;
    for (int a = 0; a < n && apex < 0; ++a) {
      bool ok = true;
      for (int i = 0; i < n; ++i) {
        if (i == a || i == (a + 1) % n || i == (a + n - 1) % n) continue;
        if ((kCubeEdgeFaceMask[loop[a]] & kCubeEdgeFaceMask[loop[i]]) != 0) ok = false;
      }
      if (ok) apex = a;
    }

    auto add = [&result](int p, int q, int r) {
      result.triangles[result.triangle_count++] = {
          static_cast<std::uint8_t>(p), static_cast<std::uint8_t>(q), static_cast<std::uint8_t>(r)};
    };
    if (apex >= 0) {
      for (int i = 1; i + 1 < n; ++i) {
        add(loop[apex], loop[(apex + i) % n], loop[(apex + i + 1) % n]);
      }
    } else {
      const int centre = kFirstCentroid + result.centroid_count;
      std::uint16_t edges = 0;
      for (int i = 0; i < n; ++i) edges = static_cast<std::uint16_t>(edges | (1u << loop[i]));
      result.centroid_edges[result.centroid_count++] = edges;
      for (int i = 0; i < n; ++i) add(centre, loop[i], loop[(i + 1) % n]);
    }
  }
  return result;
}

// All triangulations the extractor can use for one decision rule, indexed by cube index and
// the decisions on that index's ambiguous faces. Entry first[c] + d holds cube index c where
// bit k of d is the decision (1 = joined) on the k-th ambiguous face of c in face order; a
// cube without ambiguous faces has the single entry first[c].
template <std::size_t N>
struct CaseTable {
  std::array<std::uint16_t, 256> first{};
  std::array<std::uint8_t, 256> decided_faces{};  // faces whose decision selects the entry
  std::array<CubeCase, N> cases{};
};

namespace detail {

constexpr std::size_t consistent_case_count() {
  std::size_t n = 0;
  for (unsigned c = 0; c < 256; ++c) n += std::size_t{1} << std::popcount(kCubeAmbiguousFaces[c]);
  return n;
}

// Spreads the bits of `compact` onto the set bits of `mask` (lowest first).
constexpr unsigned deposit_bits(unsigned compact, unsigned mask) {
  unsigned out = 0;
  for (int bit = 0, k = 0; bit < 8; ++bit) {
    if (((mask >> bit) & 1u) == 0) continue;
    if (((compact >> k) & 1u) != 0) out |= 1u << bit;
    ++k;
  }
  return out;
}

}  // namespace detail

inline constexpr std::size_t kConsistentCaseCount = detail::consistent_case_count();

// Consistent mode: every combination of face decisions, to be selected per cube by the
// asymptotic decider.
inline constexpr CaseTable<kConsistentCaseCount> kConsistentCases = [] {
  CaseTable<kConsistentCaseCount> table{};
  std::size_t at = 0;
  for (unsigned c = 0; c < 256; ++c) {
    const unsigned faces = kCubeAmbiguousFaces[c];
    table.first[c] = static_cast<std::uint16_t>(at);
    table.decided_faces[c] = static_cast<std::uint8_t>(faces);
    for (unsigned d = 0; d < (1u << std::popcount(faces)); ++d) {
      table.cases[at++] = triangulate_cube(c, detail::deposit_bits(d, faces));
    }
  }
  return table;
}();

// Classic mode: one fixed triangulation per index, like a Lorensen table built from 128
// representatives and their complements (spec §1.1, §5.2): a cube with v7 outside (index <
// 128) separates its inside corners on every ambiguous face, its complement separates the
// outside corners instead. Two cubes that share an ambiguous face but differ in v7 therefore
// disagree on it, which leaves the holes the consistent mode removes.
inline constexpr CaseTable<256> kClassicCases = [] {
  CaseTable<256> table{};
  for (unsigned c = 0; c < 256; ++c) {
    table.first[c] = static_cast<std::uint16_t>(c);
    table.cases[c] = triangulate_cube(c, c < 128 ? 0u : 0x3Fu);
  }
  return table;
}();

// ---- Invariants ------------------------------------------------------------------------------

namespace detail {

constexpr bool edges_run_lower_to_upper() {
  for (const auto& ends : kCubeEdgeVertices) {
    int steps = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const int d = kCubeVertexOffset[ends[1]][axis] - kCubeVertexOffset[ends[0]][axis];
      if (d < 0) return false;
      steps += d;
    }
    if (steps != 1) return false;
  }
  return true;
}

constexpr bool faces_wind_outward() {
  for (int f = 0; f < kCubeFaceCount; ++f) {
    const auto& p0 = kCubeVertexOffset[kCubeFaceVertices[f][0]];
    const auto& p1 = kCubeVertexOffset[kCubeFaceVertices[f][1]];
    const auto& p3 = kCubeVertexOffset[kCubeFaceVertices[f][3]];
    const int a[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    const int b[3] = {p3[0] - p0[0], p3[1] - p0[1], p3[2] - p0[2]};
    const int n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                      a[0] * b[1] - a[1] * b[0]};
    for (int axis = 0; axis < 3; ++axis) {
      const int want = axis == f / 2 ? (f % 2 ? 1 : -1) : 0;
      if (n[axis] != want) return false;
    }
    for (int e : kCubeFaceEdges[f]) {
      if (e < 0) return false;
    }
  }
  return true;
}

constexpr bool every_edge_in_two_faces() {
  for (auto mask : kCubeEdgeFaceMask) {
    if (std::popcount(mask) != 2) return false;
  }
  return true;
}

// Every cut edge is used by the triangulation, and triangles per loop are n−2 (fan) or n
// (centre fan); so the counts must lie between cut − 2·loops and cut.
constexpr bool cases_cover_cut_edges() {
  for (const auto& cube_case : kConsistentCases.cases) {
    if (cube_case.triangle_count > kMaxCaseTriangles) return false;
    if (cube_case.centroid_count > kMaxCaseCentroids) return false;
  }
  for (unsigned c = 0; c < 256; ++c) {
    const CubeCase& cube_case = kConsistentCases.cases[kConsistentCases.first[c]];
    unsigned used = 0;
    for (int t = 0; t < cube_case.triangle_count; ++t) {
      for (auto v : cube_case.triangles[t]) {
        if (v < kFirstCentroid) used |= 1u << v;
      }
    }
    if (used != kCubeCutEdges[c]) return false;
  }
  return true;
}

}  // namespace detail

static_assert(detail::edges_run_lower_to_upper());
static_assert(detail::faces_wind_outward());
static_assert(detail::every_edge_in_two_faces());
static_assert(detail::cases_cover_cut_edges());
static_assert(kCubeEdgeLattice[10].axis == 2 && kCubeEdgeLattice[10].offset[1] == 1 &&
              kCubeEdgeLattice[10].offset[0] == 0);  // e10 = v3–v7, not Bourke's v2–v6
static_assert(kCubeEdgeLattice[11].axis == 2 && kCubeEdgeLattice[11].offset[0] == 1 &&
              kCubeEdgeLattice[11].offset[1] == 1);  // e11 = v2–v6
static_assert(kCubeAmbiguousFaces[0] == 0 && kCubeAmbiguousFaces[255] == 0);
// Case 13 (inside corners v0, v2, v5, v7): all six faces ambiguous.
static_assert(kCubeAmbiguousFaces[0b10100101] == 0x3F);
// One corner inside: one loop; two opposite corners (v0, v6: case 4): two loops.
static_assert(kConsistentCases.cases[kConsistentCases.first[1]].loop_count == 1);
static_assert(kConsistentCases.cases[kConsistentCases.first[0b01000001]].loop_count == 2);
// The classic table equals the consistent table on every unambiguous cube.
static_assert(kClassicCases.cases[1] == kConsistentCases.cases[kConsistentCases.first[1]]);

}  // namespace typemerge::core
