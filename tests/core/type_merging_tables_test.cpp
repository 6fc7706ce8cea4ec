// Tests of type_merging_tables.h: the generated moving table against spec §2.3 and against
// the slide geometry; the generated type table against Appendix A; and the property that
// defines the type table: on a plane containing d, a cube whose index lists d repeats at C + d;
// the type-3 blocks against spec §3.4 and against random planes.
#include "type_merging_tables.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace typemerge::core {
namespace {

int direction_of(const std::string& name) {
  for (int d = 0; d < kMergeDirectionCount; ++d) {
    if (name == kMergeDirectionName[d]) return d;
  }
  ADD_FAILURE() << "unknown direction " << name;
  return 0;
}

// ---- Moving table --------------------------------------------------------------------------

struct SpecMoveRow {
  const char* direction;
  std::array<int, 4> fixed;
  std::array<std::array<int, 2>, 4> moves;
};

// Spec §2.3, copied by hand (the rows LT, FD, LF are the corrected ones).
constexpr SpecMoveRow kSpecMoves[] = {
    {"R", {0, 2, 4, 6}, {{{3, 1}, {7, 5}, {8, 9}, {10, 11}}}},
    {"T", {1, 3, 5, 7}, {{{0, 2}, {4, 6}, {8, 10}, {9, 11}}}},
    {"F", {8, 9, 10, 11}, {{{0, 4}, {1, 5}, {2, 6}, {3, 7}}}},
    {"TR", {8, 9, 10, 11}, {{{0, 1}, {3, 2}, {4, 5}, {7, 6}}}},
    {"LT", {8, 9, 10, 11}, {{{0, 3}, {1, 2}, {4, 7}, {5, 6}}}},
    {"TF", {0, 2, 4, 6}, {{{1, 11}, {3, 10}, {8, 7}, {9, 5}}}},
    {"FD", {0, 2, 4, 6}, {{{1, 9}, {3, 8}, {10, 7}, {11, 5}}}},
    {"FR", {1, 3, 5, 7}, {{{0, 9}, {2, 11}, {8, 4}, {10, 6}}}},
    {"LF", {1, 3, 5, 7}, {{{0, 8}, {2, 10}, {9, 4}, {11, 6}}}},
};

TEST(TypeMergingTables, MovingTableEqualsSpecSection2_3) {
  for (const SpecMoveRow& spec : kSpecMoves) {
    SCOPED_TRACE(spec.direction);
    const MoveRow& row = kMoveTable[direction_of(spec.direction)];
    unsigned fixed = 0;
    for (int e : spec.fixed) fixed |= 1u << e;
    EXPECT_EQ(row.fixed, fixed);
    ASSERT_EQ(row.move_count, 4);
    for (const auto& move : spec.moves) {
      bool found = false;
      for (int m = 0; m < row.move_count; ++m) {
        found = found || (row.moves[m].source == move[0] && row.moves[m].target == move[1]);
      }
      EXPECT_TRUE(found) << "e" << move[0] << " -> e" << move[1];
    }
  }
}

// The paper's printed rows for FD, LT, LF (spec §2.2) are the reverses of TF, TR, FR; the
// generated rows must differ from them.
TEST(TypeMergingTables, PrintedFdLtLfRowsAreNotUsed) {
  const std::array<std::pair<const char*, std::array<std::array<int, 2>, 4>>, 3> printed{{
      {"FD", {{{11, 1}, {10, 3}, {7, 8}, {5, 9}}}},
      {"LT", {{{1, 0}, {2, 3}, {5, 4}, {6, 7}}}},
      {"LF", {{{9, 0}, {11, 2}, {4, 8}, {6, 10}}}},
  }};
  for (const auto& [name, moves] : printed) {
    const MoveRow& row = kMoveTable[direction_of(name)];
    for (const auto& move : moves) {
      for (int m = 0; m < row.move_count; ++m) {
        EXPECT_FALSE(row.moves[m].source == move[0] && row.moves[m].target == move[1]) << name;
      }
    }
  }
}

// Spec §7.2: sliding the midpoint of s along d inside the cube reaches the midpoint of t, in
// a face that contains both edges; fixed edges are parallel to d or rails (spec §2.1).
TEST(TypeMergingTables, MovesAreSlidesAlongTheDirection) {
  auto midpoint2 = [](int e) {  // doubled
    const auto& a = kCubeVertexOffset[kCubeEdgeVertices[e][0]];
    const auto& b = kCubeVertexOffset[kCubeEdgeVertices[e][1]];
    return std::array<int, 3>{a[0] + b[0], a[1] + b[1], a[2] + b[2]};
  };
  for (int d = 0; d < kMergeDirectionCount; ++d) {
    SCOPED_TRACE(kMergeDirectionName[d]);
    const auto& u = kMergeDirectionVector[d];
    const bool primary = std::abs(u[0]) + std::abs(u[1]) + std::abs(u[2]) == 1;
    for (int m = 0; m < kMoveTable[d].move_count; ++m) {
      const int s = kMoveTable[d].moves[m].source;
      const int t = kMoveTable[d].moves[m].target;
      const auto ms = midpoint2(s);
      const auto mt = midpoint2(t);
      const int step = primary ? 2 : 1;  // doubled: one cube step, or half a diagonal
      for (int a = 0; a < 3; ++a) EXPECT_EQ(mt[a] - ms[a], step * u[a]) << "e" << s;
      EXPECT_NE(kCubeEdgeFaceMask[s] & kCubeEdgeFaceMask[t], 0);
    }
    for (int e = 0; e < kCubeEdgeCount; ++e) {
      if (((kMoveTable[d].fixed >> e) & 1u) == 0) continue;
      const int axis = detail::edge_axis(e);
      int other_components = 0;
      for (int a = 0; a < 3; ++a) other_components += a != axis && u[a] != 0 ? 1 : 0;
      EXPECT_TRUE(primary ? u[axis] != 0 : other_components == 2) << "e" << e;
    }
  }
}

// ---- Type table ----------------------------------------------------------------------------

struct SpecTypeRow {
  int index;
  int type;            // paper type; minors and hexagons are 2
  const char* lines;   // Appendix A "merge directions (forward)", space separated
};

// Appendix A, copied by hand (all 51 plane-producible representatives). Type 0 rows list the
// two primaries only (the paper's merge directions).
constexpr SpecTypeRow kAppendixA[] = {
    {1, 2, "FD LT LF"},  {2, 2, "FD FR TR"},  {3, 1, "R FD"},      {4, 2, "TF LT FR"},
    {6, 1, "T FR"},      {7, 2, "TR"},        {8, 2, "TF LF TR"},  {9, 1, "T LF"},
    {11, 2, "LT"},       {12, 1, "R TF"},     {13, 2, "TR"},       {14, 2, "LT"},
    {15, 0, "T R"},      {16, 2, "TF LT FR"}, {17, 1, "F LT"},     {19, 2, "LF"},
    {25, 2, "FD"},       {27, 2, "FD LT LF"}, {31, 2, "LT"},       {32, 2, "TF LF TR"},
    {34, 1, "F TR"},     {35, 2, "FR"},       {38, 2, "FD"},       {39, 2, "FD FR TR"},
    {47, 2, "TR"},       {48, 1, "R TF"},     {49, 2, "FR"},       {50, 2, "LF"},
    {51, 0, "F R"},      {55, 2, "FR"},       {59, 2, "LF"},       {63, 1, "R FD"},
    {64, 2, "FD LT LF"}, {68, 1, "F LT"},     {70, 2, "TF"},       {76, 2, "FR"},
    {78, 2, "TF LT FR"}, {79, 2, "LT"},       {96, 1, "T LF"},     {98, 2, "TF"},
    {100, 2, "FD"},      {102, 0, "F T"},     {103, 2, "FD"},      {110, 2, "TF"},
    {111, 1, "T FR"},    {112, 2, "TR"},      {114, 2, "TF LF TR"}, {115, 2, "LF"},
    {118, 2, "TF"},      {119, 1, "F TR"},    {127, 2, "FD FR TR"},
};

unsigned parse_directions(const std::string& text) {
  unsigned mask = 0;
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t end = text.find(' ', at);
    mask |= 1u << direction_of(text.substr(at, end - at));
    at = end == std::string::npos ? text.size() : end + 1;
  }
  return mask;
}

TEST(TypeMergingTables, TypeTableEqualsAppendixA) {
  std::array<bool, 128> listed{};
  for (const SpecTypeRow& spec : kAppendixA) {
    SCOPED_TRACE(spec.index);
    listed[spec.index] = true;
    const TypeEntry& entry = kTypeTable[spec.index];
    EXPECT_TRUE(entry.plane_producible);
    EXPECT_EQ(paper_type(entry.type), spec.type);
    const unsigned dirs = parse_directions(spec.lines);
    if (spec.type == 0) {
      EXPECT_EQ(entry.merge, dirs);
    } else {
      EXPECT_EQ(entry.lines, dirs);
    }
  }
  for (unsigned c = 1; c < 128; ++c) {
    if (listed[c]) continue;
    SCOPED_TRACE(c);
    EXPECT_FALSE(kTypeTable[c].plane_producible);
    EXPECT_EQ(kTypeTable[c].type, CubeType::kNone);
  }
}

// Spec §3.2/§3.3: the minors are 1, 2, 4, 8, 16, 32, 64, 127; the hexagons 27, 39, 78, 114 merge
// along the paper's two lines with an x component (78: LT, FR; 114: LF, TR; 27: LT, LF;
// 39: TR, FR); type 0 merges along its two primaries.
TEST(TypeMergingTables, MinorsHexagonsAndPaperDirections) {
  for (unsigned c : {1u, 2u, 4u, 8u, 16u, 32u, 64u, 127u}) {
    EXPECT_EQ(kTypeTable[c].type, CubeType::kMinor) << c;
  }
  EXPECT_EQ(kTypeTable[78].merge, parse_directions("LT FR"));
  EXPECT_EQ(kTypeTable[114].merge, parse_directions("LF TR"));
  EXPECT_EQ(kTypeTable[27].merge, parse_directions("LT LF"));
  EXPECT_EQ(kTypeTable[39].merge, parse_directions("TR FR"));
  EXPECT_EQ(kTypeTable[15].merge, parse_directions("T R"));
  // Complement symmetry: the type is looked up by representative.
  for (unsigned c = 0; c < 256; ++c) EXPECT_EQ(&type_of(c), &type_of(255 - c));
}

// Cube index at lattice point (x, y, z) for the plane 2·n·p < t2 (inside; t2 odd, so the plane
// never passes through a lattice point).
unsigned plane_cube_index(const std::array<int, 3>& n, int t2, int x, int y, int z) {
  unsigned c = 0;
  for (int v = 0; v < kCubeVertexCount; ++v) {
    const auto& o = kCubeVertexOffset[v];
    const int value = n[0] * (x + o[0]) + n[1] * (y + o[1]) + n[2] * (z + o[2]);
    if (2 * value < t2) c |= 1u << v;
  }
  return c;
}

// Spec §7.3: random planes with small integral normals orthogonal to a table direction d:
// every boundary cube whose index lists d has the same index at C + d; and the table is
// complete: every boundary cube such a plane makes lists d.
TEST(TypeMergingTables, PlanesContainingADirectionRepeatTheirCubesAlongIt) {
  std::mt19937 rng(1996);
  std::uniform_int_distribution<int> component(-3, 3);
  int planes = 0;
  int cubes_checked = 0;
  while (planes < 400) {
    const std::array<int, 3> n{component(rng), component(rng), component(rng)};
    const int d = std::uniform_int_distribution<int>(0, kMergeDirectionCount - 1)(rng);
    const auto& u = kMergeDirectionVector[d];
    if (n == std::array<int, 3>{0, 0, 0} || n[0] * u[0] + n[1] * u[1] + n[2] * u[2] != 0) continue;
    ++planes;
    const int t2 = 2 * std::uniform_int_distribution<int>(-6, 6)(rng) + 1;
    for (int z = -3; z <= 3; ++z) {
      for (int y = -3; y <= 3; ++y) {
        for (int x = -3; x <= 3; ++x) {
          const unsigned c = plane_cube_index(n, t2, x, y, z);
          if (c == 0 || c == 255) continue;
          const TypeEntry& entry = type_of(c);
          ASSERT_TRUE(entry.plane_producible) << c;
          EXPECT_NE(entry.lines & (1u << d), 0u)
              << "plane (" << n[0] << "," << n[1] << "," << n[2] << ") makes " << c
              << " but the table does not list " << kMergeDirectionName[d];
          EXPECT_EQ(plane_cube_index(n, t2, x + u[0], y + u[1], z + u[2]), c);
          ++cubes_checked;
        }
      }
    }
  }
  EXPECT_GT(cubes_checked, 10000);
}

// Conversely every listed line is realised: for each representative and each of its lines
// some plane containing the line creates it (so no direction is listed without a reason).
TEST(TypeMergingTables, EveryListedLineHasAPlane) {
  for (unsigned c = 1; c < 128; ++c) {
    for (int d = 0; d < kMergeDirectionCount; ++d) {
      if (((kTypeTable[c].lines >> d) & 1u) == 0) continue;
      const auto& u = kMergeDirectionVector[d];
      bool realised = false;
      for (int nx = -3; nx <= 3 && !realised; ++nx) {
        for (int ny = -3; ny <= 3 && !realised; ++ny) {
          for (int nz = -3; nz <= 3 && !realised; ++nz) {
            if (nx * u[0] + ny * u[1] + nz * u[2] != 0 || (nx == 0 && ny == 0 && nz == 0)) continue;
            for (int t2 = -19; t2 <= 19 && !realised; t2 += 2) {
              const unsigned k = plane_cube_index({nx, ny, nz}, t2, 0, 0, 0);
              realised = detail::complement_rep(k) == c;
            }
          }
        }
      }
      EXPECT_TRUE(realised) << c << " along " << kMergeDirectionName[d];
    }
  }
}

// ---- Type 3 (spec §3.4) ------------------------------------------------------------------------

bool has_type3_block(std::size_t plane, std::uint32_t key) {
  const auto& blocks = type3_blocks()[plane];
  return std::any_of(blocks.begin(), blocks.end(),
                     [&](const Type3Block& b) { return b.key == key; });
}

// The four groups of spec §3.4 (complement representatives; the fixed cubes, then the two
// choices at each variable position), in the slice plane.
struct SpecGroup {
  const char* name;
  bool bold_bl_tr;
  // BL, BR, TL, TR: one value where the cube is fixed, two where it varies.
  std::array<std::array<unsigned, 2>, 4> cubes;
};
constexpr SpecGroup kSpecGroups[] = {
    {"G1", true, {{{4, 4}, {78, 110}, {70, 78}, {16, 16}}}},
    {"G2", true, {{{64, 64}, {27, 59}, {19, 27}, {1, 1}}}},
    {"G3", false, {{{39, 55}, {127, 127}, {2, 2}, {35, 39}}}},
    {"G4", false, {{{98, 114}, {8, 8}, {32, 32}, {114, 118}}}},
};

TEST(TypeMergingTables, Type3BlocksIncludeTheSpecGroups) {
  // The spec names cubes by complement representative, each cube on its own (one plane can
  // make 4 next to 177, whose representative is 78): compare blocks that way.
  std::set<std::array<unsigned, 4>> reps;
  std::set<std::array<unsigned, 4>> bold_bl_tr;
  for (const Type3Block& block : type3_blocks()[0]) {
    std::array<unsigned, 4> r{};
    for (int k = 0; k < 4; ++k) r[k] = detail::complement_rep((block.key >> (8 * k)) & 0xFFu);
    reps.insert(r);
    if (block.bold_bl_tr) bold_bl_tr.insert(r);
  }
  for (const SpecGroup& group : kSpecGroups) {
    SCOPED_TRACE(group.name);
    for (unsigned choice = 0; choice < 16; ++choice) {
      std::array<unsigned, 4> r{};
      for (int k = 0; k < 4; ++k) r[k] = group.cubes[k][(choice >> k) & 1u];
      EXPECT_EQ(reps.count(r), 1u) << r[0] << " " << r[1] << " " << r[2] << " " << r[3];
      EXPECT_EQ(bold_bl_tr.count(r), group.bold_bl_tr ? 1u : 0u);
    }
  }
  // 28 blocks up to complement (spec out/type3_groups.md lists 28 for the slice): the 16
  // combinations of G1–G4 and their mirror images; the same count in the other two planes.
  EXPECT_EQ(reps.size(), 28u);
  for (std::size_t plane = 0; plane < 3; ++plane) EXPECT_EQ(type3_blocks()[plane].size(), 56u);
}

// Every block whose diagonal cubes are corner configurations that a random (real) plane makes
// is in the table, every table entry is made by some plane, and in every one the block's
// centre edge is cut in all four cubes.
TEST(TypeMergingTables, Type3BlocksAreExactlyWhatPlanesMake) {
  std::mt19937 rng(1996);
  std::normal_distribution<double> gaussian;
  std::uniform_real_distribution<double> offset(-2.0, 2.0);
  auto corner = [](unsigned c) { return std::popcount(c) == 1 || std::popcount(c) == 7; };
  for (std::size_t plane = 0; plane < 3; ++plane) {
    const Type3Plane& axes = kType3Planes[plane];
    std::set<std::uint32_t> seen;
    for (int trial = 0; trial < 200000; ++trial) {
      const std::array<double, 3> n{gaussian(rng), gaussian(rng), gaussian(rng)};
      const double t = offset(rng);
      auto cube = [&](const std::array<int, 3>& origin) {
        unsigned c = 0;
        for (int v = 0; v < kCubeVertexCount; ++v) {
          const auto& o = kCubeVertexOffset[v];
          double value = 0.0;
          for (int i = 0; i < 3; ++i) value += n[i] * (origin[i] + o[i]);
          if (value > t) c |= 1u << v;
        }
        return c;
      };
      const std::array<int, 3> hv{axes.h[0] + axes.v[0], axes.h[1] + axes.v[1],
                                  axes.h[2] + axes.v[2]};
      const unsigned bl = cube({0, 0, 0});
      const unsigned br = cube(axes.h);
      const unsigned tl = cube(axes.v);
      const unsigned tr = cube(hv);
      bool cut = true;
      for (unsigned c : {bl, br, tl, tr}) cut = cut && c != 0 && c != 255;
      if (!cut || (!(corner(bl) && corner(tr)) && !(corner(tl) && corner(br)))) continue;
      const std::uint32_t key = type3_key(bl, br, tl, tr);
      ASSERT_TRUE(has_type3_block(plane, key)) << plane << ": " << key;
      seen.insert(key);
    }
    EXPECT_EQ(seen.size(), type3_blocks()[plane].size()) << "plane " << plane;
    for (const Type3Block& block : type3_blocks()[plane]) {
      // The centre edge, h + v .. h + v + w in block coordinates, in each cube.
      for (int k = 0; k < 4; ++k) {
        const unsigned c = (block.key >> (8 * k)) & 0xFFu;
        std::array<int, 3> from{};
        for (int i = 0; i < 3; ++i) {
          from[i] = axes.h[i] * ((k & 1) != 0 ? 0 : 1) + axes.v[i] * ((k & 2) != 0 ? 0 : 1);
        }
        int lower = -1;
        int upper = -1;
        for (int v = 0; v < kCubeVertexCount; ++v) {
          const auto& o = kCubeVertexOffset[v];
          if (o == from) lower = v;
          if (o[0] == from[0] + axes.w[0] && o[1] == from[1] + axes.w[1] &&
              o[2] == from[2] + axes.w[2]) {
            upper = v;
          }
        }
        ASSERT_GE(lower, 0);
        ASSERT_GE(upper, 0);
        EXPECT_NE((c >> lower) & 1u, (c >> upper) & 1u) << "block " << block.key << " cube " << k;
      }
      const unsigned bl = block.key & 0xFFu;
      const unsigned tr = block.key >> 24;
      EXPECT_EQ(block.bold_bl_tr, corner(bl) && corner(tr));
    }
  }
  // The enumeration behind the table is complete at normal components of 3 (as the type
  // table's, spec §3.1): 6 finds nothing more.
  for (std::size_t plane = 0; plane < 3; ++plane) {
    EXPECT_EQ(detail::enumerate_type3_blocks(kType3Planes[plane], 6).size(),
              type3_blocks()[plane].size());
  }
}

}  // namespace
}  // namespace typemerge::core
