// Tests of cube_tables.h: the numbering against spec §1.1–1.2, and the face-loop
// triangulations exhaustively (every cube index × every decision on its ambiguous faces).
#include "core/cube_tables.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <utility>
#include <vector>

namespace typemerge::core {
namespace {

// Spec §1.2, typed in again here on purpose: the test is the independent copy.
struct EdgeRow {
  int a, b;        // endpoints
  int axis;        // 0 = x, 1 = y, 2 = z
  int dx, dy, dz;  // start of the lattice edge relative to the cube
};
constexpr EdgeRow kSpecEdges[12] = {{0, 1, 0, 0, 0, 0}, {1, 2, 1, 1, 0, 0}, {3, 2, 0, 0, 1, 0},
                                    {0, 3, 1, 0, 0, 0}, {4, 5, 0, 0, 0, 1}, {5, 6, 1, 1, 0, 1},
                                    {7, 6, 0, 0, 1, 1}, {4, 7, 1, 0, 0, 1}, {0, 4, 2, 0, 0, 0},
                                    {1, 5, 2, 1, 0, 0}, {3, 7, 2, 0, 1, 0}, {2, 6, 2, 1, 1, 0}};

TEST(CubeTables, VerticesFollowLorensenOrder) {
  const int expected[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                              {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (int v = 0; v < 8; ++v) {
    for (int a = 0; a < 3; ++a) EXPECT_EQ(kCubeVertexOffset[v][a], expected[v][a]) << "v" << v;
  }
}

TEST(CubeTables, EdgesMatchSpecTable) {
  for (int e = 0; e < 12; ++e) {
    SCOPED_TRACE(testing::Message() << "e" << e);
    EXPECT_EQ(kCubeEdgeVertices[e][0], kSpecEdges[e].a);
    EXPECT_EQ(kCubeEdgeVertices[e][1], kSpecEdges[e].b);
    EXPECT_EQ(kCubeEdgeLattice[e].axis, kSpecEdges[e].axis);
    EXPECT_EQ(kCubeEdgeLattice[e].offset[0], kSpecEdges[e].dx);
    EXPECT_EQ(kCubeEdgeLattice[e].offset[1], kSpecEdges[e].dy);
    EXPECT_EQ(kCubeEdgeLattice[e].offset[2], kSpecEdges[e].dz);
  }
}

TEST(CubeTables, FacesHoldTheirVerticesAndEdges) {
  for (int f = 0; f < 6; ++f) {
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(kCubeVertexOffset[kCubeFaceVertices[f][k]][f / 2], f % 2);
      const int e = kCubeFaceEdges[f][k];
      EXPECT_TRUE((kCubeEdgeFaceMask[e] >> f) & 1u);
    }
  }
}

// MC base cases with ambiguous faces (Lorensen numbering, with complements): case 3 (24
// configurations) and 6 (48) have one, 10 (6) and 12 (24) two, 7 (16) three, 13 (2) six.
TEST(CubeTables, AmbiguousFaceCountsMatchTheKnownCases) {
  int histogram[7] = {};
  for (unsigned c = 0; c < 256; ++c) ++histogram[std::popcount(kCubeAmbiguousFaces[c])];
  EXPECT_EQ(histogram[1], 24 + 48);
  EXPECT_EQ(histogram[2], 6 + 24);
  EXPECT_EQ(histogram[3], 16);
  EXPECT_EQ(histogram[4], 0);
  EXPECT_EQ(histogram[5], 0);
  EXPECT_EQ(histogram[6], 2);
  EXPECT_EQ(histogram[0], 256 - 72 - 30 - 16 - 2);
}

using Triangles = std::vector<std::array<std::uint8_t, 3>>;

Triangles triangles_of(const CubeCase& c) {
  return Triangles(c.triangles.begin(), c.triangles.begin() + c.triangle_count);
}

// One inside corner v0: one triangle through its three edges e0, e3, e8, wound so that the
// normal (+,+,+) points away from v0.
TEST(CubeTables, CornerCaseIsOneOutwardTriangle) {
  EXPECT_EQ(triangles_of(triangulate_cube(0b00000001, 0)), (Triangles{{0, 3, 8}}));
  // The complement: same loop, the other way round.
  EXPECT_EQ(triangles_of(triangulate_cube(0b11111110, 0)), (Triangles{{0, 8, 3}}));
}

TEST(CubeTables, EdgeCaseIsAQuadWithAnInteriorDiagonal) {
  // v0, v1 inside: loop e1 → e3 → e8 → e9, fanned from e1; the diagonal e1–e8 crosses the cube.
  EXPECT_EQ(triangles_of(triangulate_cube(0b00000011, 0)), (Triangles{{1, 3, 8}, {1, 8, 9}}));
}

TEST(CubeTables, AmbiguousFaceDecisionChangesTheLoops) {
  // v0 and v2 inside (case 3): face z-low (f4) is ambiguous.
  const unsigned c = 0b00000101;
  ASSERT_EQ(kCubeAmbiguousFaces[c], 1u << 4);
  // Separated: two corner triangles.
  EXPECT_EQ(triangulate_cube(c, 0).triangle_count, 2);
  EXPECT_EQ(triangulate_cube(c, 0).centroid_count, 0);
  // Joined: one hexagon through the cube, 4 triangles.
  EXPECT_EQ(triangulate_cube(c, 1u << 4).triangle_count, 4);
}

// Per triangulation: every triangle edge that is not a contour segment on a face is used
// twice, in opposite directions (so the patch is a disk per loop); the segments lie on faces,
// are used once, and there are as many on each face as the face's crossings require.
void expect_patch_is_bounded_by_face_segments(unsigned c, unsigned joined) {
  const CubeCase cube_case = triangulate_cube(c, joined);
  std::map<std::pair<int, int>, int> directed;
  for (int t = 0; t < cube_case.triangle_count; ++t) {
    const auto& tri = cube_case.triangles[t];
    for (int k = 0; k < 3; ++k) ++directed[{tri[k], tri[(k + 1) % 3]}];
  }
  int segments_per_face[6] = {};
  for (const auto& [edge, uses] : directed) {
    EXPECT_EQ(uses, 1);
    const auto [a, b] = edge;
    const bool reverse_used = directed.count({b, a}) != 0;
    const bool on_face = a < kFirstCentroid && b < kFirstCentroid &&
                         (kCubeEdgeFaceMask[a] & kCubeEdgeFaceMask[b]) != 0;
    EXPECT_NE(reverse_used, on_face) << "edge " << a << "-" << b;
    if (on_face) {
      ++segments_per_face[std::countr_zero(
          static_cast<unsigned>(kCubeEdgeFaceMask[a] & kCubeEdgeFaceMask[b]))];
    }
  }
  for (int f = 0; f < 6; ++f) {
    int crossings = 0;
    for (int e : kCubeFaceEdges[f]) crossings += (kCubeCutEdges[c] >> e) & 1u;
    EXPECT_EQ(segments_per_face[f], crossings / 2) << "face " << f;
  }
}

TEST(CubeTables, EveryTriangulationIsBoundedByFaceSegments) {
  for (unsigned c = 1; c < 255; ++c) {
    for (unsigned joined = 0; joined < 64; ++joined) {
      if ((joined & ~unsigned{kCubeAmbiguousFaces[c]}) != 0) continue;
      SCOPED_TRACE(testing::Message() << "index " << c << " joined " << joined);
      expect_patch_is_bounded_by_face_segments(c, joined);
    }
  }
}

// The directed contour segments a cube draws on face f, as pairs of lattice edges (offset
// relative to the cube at `origin`, axis).
using LatticeKey = std::array<int, 4>;
std::vector<std::pair<LatticeKey, LatticeKey>> face_segments(const CubeCase& cube_case, int f,
                                                             std::array<int, 3> origin) {
  auto key = [&origin](int e) {
    const LatticeEdge& l = kCubeEdgeLattice[e];
    return LatticeKey{origin[0] + l.offset[0], origin[1] + l.offset[1], origin[2] + l.offset[2],
                      l.axis};
  };
  std::vector<std::pair<LatticeKey, LatticeKey>> out;
  for (int t = 0; t < cube_case.triangle_count; ++t) {
    const auto& tri = cube_case.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const int a = tri[k];
      const int b = tri[(k + 1) % 3];
      if (a >= kFirstCentroid || b >= kFirstCentroid) continue;
      if (((kCubeEdgeFaceMask[a] & kCubeEdgeFaceMask[b]) >> f & 1u) == 0) continue;
      out.emplace_back(key(a), key(b));
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The invariant that makes the surface watertight: two cubes sharing a face with the same
// decision draw the same segments on it, in opposite directions. Checked for every cube index,
// every decision set, every face and every configuration of the neighbour's far side.
TEST(CubeTables, NeighboursDrawOppositeSegmentsOnASharedFace) {
  for (unsigned c = 1; c < 255; ++c) {
    for (unsigned joined = 0; joined < 64; ++joined) {
      if ((joined & ~unsigned{kCubeAmbiguousFaces[c]}) != 0) continue;
      const CubeCase mine = triangulate_cube(c, joined);
      for (int f = 0; f < 6; ++f) {
        const int axis = f / 2;
        std::array<int, 3> shift{0, 0, 0};
        shift[axis] = f % 2 ? 1 : -1;
        // The neighbour's vertices on the shared face copy ours; its far side varies.
        unsigned shared = 0;
        for (int v = 0; v < 8; ++v) {
          const auto& o = kCubeVertexOffset[v];
          if (o[axis] != f % 2) continue;
          std::array<int, 3> p = o;
          p[axis] -= shift[axis];
          const int w = detail::vertex_at(p[0], p[1], p[2]);
          if ((c >> v) & 1u) shared |= 1u << w;
        }
        const int g = f ^ 1;
        std::vector<int> far;
        for (int v = 0; v < 8; ++v) {
          if (kCubeVertexOffset[v][axis] != g % 2) far.push_back(v);
        }
        for (unsigned bits = 0; bits < 16; ++bits) {
          unsigned neighbour = shared;
          for (int k = 0; k < 4; ++k) {
            if ((bits >> k) & 1u) neighbour |= 1u << far[k];
          }
          const unsigned neighbour_joined = ((joined >> f) & 1u) << g;
          const auto theirs =
              face_segments(triangulate_cube(neighbour, neighbour_joined), g, shift);
          auto reversed = face_segments(mine, f, {0, 0, 0});
          for (auto& s : reversed) std::swap(s.first, s.second);
          std::sort(reversed.begin(), reversed.end());
          ASSERT_EQ(theirs, reversed) << "index " << c << " joined " << joined << " face " << f
                                      << " neighbour " << neighbour;
        }
      }
    }
  }
}

TEST(CubeTables, TablesHoldTheConstruction) {
  for (unsigned c = 0; c < 256; ++c) {
    const unsigned faces = kCubeAmbiguousFaces[c];
    const int count = 1 << std::popcount(faces);
    for (int d = 0; d < count; ++d) {
      EXPECT_EQ(kConsistentCases.cases[kConsistentCases.first[c] + d],
                triangulate_cube(c, detail::deposit_bits(static_cast<unsigned>(d), faces)));
    }
    EXPECT_EQ(kClassicCases.cases[c], triangulate_cube(c, c < 128 ? 0u : 0x3Fu));
  }
  EXPECT_EQ(kConsistentCaseCount, 136u + 72u * 2 + 30u * 4 + 16u * 8 + 2u * 64);
}

}  // namespace
}  // namespace typemerge::core
