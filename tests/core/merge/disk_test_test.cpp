// The disk test (core/merge/disk_test.h) on small hand-made components, one for each verdict:
// a passing disk and each of the five rejection reasons, plus a pinched box.
#include "core/merge/disk_test.h"

#include <gtest/gtest.h>

#include <vector>

#include "core/merge/local_table.h"
#include "core/merge/loop_triangulation.h"

namespace typemerge::core::merge {
namespace {

// A hand-made surface and a disk test over it: vertices added with `vertex`, triangles with
// `triangle`, all tested as one box.
struct Surface {
  std::vector<Position> positions;
  std::vector<Triangle> triangles;

  VertexId vertex(float x, float y, float z) {
    positions.push_back({x, y, z});
    return static_cast<VertexId>(positions.size() - 1);
  }
  void triangle(VertexId a, VertexId b, VertexId c) { triangles.push_back({a, b, c}); }

  struct Result {
    bool all = false;
    std::vector<DiskVerdict> verdicts;
    MergeStats stats;
    DiskStore store;
    std::vector<Triangle> kept;
  };
  // With one_piece, by test_one_piece (for a surface that is one connected piece).
  Result test(const Box& box, double epsilon, bool one_piece = false) const {
    LocalTable table(positions);
    LoopTriangulator outline({{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}});
    DiskTest disk_test(positions, triangles, Tolerance::in_voxels(epsilon), table, outline);
    const std::vector<TriangleRun> runs{{0, static_cast<std::uint32_t>(triangles.size())}};
    Result r;
    r.all = one_piece ? disk_test.test_one_piece(runs, box, r.stats)
                      : disk_test.test_triangles(runs, box, r.stats);
    for (const Component& c : disk_test.components()) r.verdicts.push_back(c.verdict);
    disk_test.record(box, 2, r.store, r.kept);
    return r;
  }
};

constexpr Box kBox2{{0, 0, 0}, {2, 2, 2}};

std::size_t rejections(const MergeStats& s) {
  return s.rejected_topology + s.rejected_facing + s.rejected_flatness + s.rejected_outline +
         s.rejected_separation;
}

// The square z = 1 across the 2-box, its corners on the side faces (the loop), fanned from a
// centre vertex at height `centre_z`:
//   v3 ---- v2
//   |  \  / |
//   |   c   |
//   |  / \  |
//   v0 ---- v1
Surface square_fan(float centre_z) {
  Surface s;
  const VertexId v0 = s.vertex(0, 0, 1), v1 = s.vertex(2, 0, 1), v2 = s.vertex(2, 2, 1),
                 v3 = s.vertex(0, 2, 1), c = s.vertex(1, 1, centre_z);
  s.triangle(v0, v1, c);
  s.triangle(v1, v2, c);
  s.triangle(v2, v3, c);
  s.triangle(v3, v0, c);
  return s;
}

TEST(DiskTest, AFlatSquareIsADiskAndIsRecordedWithItsLoop) {
  const Surface s = square_fan(1.0f);
  const auto r = s.test(kBox2, 0.5);
  EXPECT_TRUE(r.all);
  ASSERT_EQ(r.verdicts, std::vector<DiskVerdict>{DiskVerdict::kDisk});
  EXPECT_EQ(rejections(r.stats), 0u);
  ASSERT_EQ(r.store.disks.size(), 1u);
  const MergedDisk& disk = r.store.disks[0];
  EXPECT_EQ(disk.loop_size, 4u);
  EXPECT_EQ(disk.face_count, 4u);
  EXPECT_EQ(disk.vertex_count, 5u);
  EXPECT_DOUBLE_EQ(disk.band, 0.0);
  EXPECT_NEAR(disk.normal[2], 1.0, 1e-12);
  // The loop runs counter-clockwise about the normal: v0 → v1 → v2 → v3 from some start.
  const auto loop = r.store.loop_of(disk);
  std::size_t at0 = 0;
  while (loop[at0] != 0) ++at0;
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(loop[(at0 + k) % 4], k);
  EXPECT_TRUE(r.kept.empty());
}

// A tetrahedron inside the box: Euler characteristic 2, no edge on a face.
Surface tetrahedron() {
  Surface s;
  const VertexId a = s.vertex(0.5f, 0.5f, 0.5f), b = s.vertex(1.5f, 0.5f, 0.5f),
                 c = s.vertex(0.5f, 1.5f, 0.5f), d = s.vertex(0.5f, 0.5f, 1.5f);
  s.triangle(a, c, b);
  s.triangle(a, b, d);
  s.triangle(a, d, c);
  s.triangle(b, c, d);
  return s;
}

// Two corner triangles of the box meeting at one vertex on the edge x = 0, y = 0.
Surface pinched_corners() {
  Surface s;
  const VertexId m = s.vertex(0, 0, 1);
  s.triangle(m, s.vertex(1, 0, 0), s.vertex(0, 1, 0));
  s.triangle(m, s.vertex(1, 0, 2), s.vertex(0, 1, 2));
  return s;
}

TEST(DiskTest, AClosedShellIsNotADisk) {
  const auto r = tetrahedron().test(kBox2, 0.5);
  EXPECT_FALSE(r.all);
  EXPECT_EQ(r.verdicts, std::vector<DiskVerdict>{DiskVerdict::kTopology});
  EXPECT_EQ(r.stats.rejected_topology, 1u);
  EXPECT_EQ(rejections(r.stats), 1u);
  EXPECT_TRUE(r.store.disks.empty());
  EXPECT_EQ(r.kept.size(), 4u);  // it keeps its triangles
}

TEST(DiskTest, TwoLoopEdgesLeavingOneVertexPinchTheWholeBox) {
  const auto r = pinched_corners().test(kBox2, 0.5);
  EXPECT_FALSE(r.all);
  EXPECT_TRUE(r.verdicts.empty());
  EXPECT_EQ(r.stats.rejected_topology, 1u);
  EXPECT_EQ(rejections(r.stats), 1u);
  EXPECT_EQ(r.kept.size(), 2u);
}

TEST(DiskTest, AFoldedDiskDoesNotFaceOneWay) {
  // The square with two inner vertices swapped, so the middle pair of triangles is folded
  // under the rest: projected, (v0, c2, c1) and (v2, c1, c2) turn clockwise.
  Surface s;
  const VertexId v0 = s.vertex(0, 0, 1), v1 = s.vertex(2, 0, 1), v2 = s.vertex(2, 2, 1),
                 v3 = s.vertex(0, 2, 1), c1 = s.vertex(1.5f, 1, 1), c2 = s.vertex(0.5f, 1, 1);
  s.triangle(v0, v1, c2);
  s.triangle(v1, v2, c2);
  s.triangle(v2, v3, c1);
  s.triangle(v3, v0, c1);
  s.triangle(v0, c2, c1);
  s.triangle(v2, c1, c2);
  const auto r = s.test(kBox2, 0.5);
  EXPECT_FALSE(r.all);
  EXPECT_EQ(r.verdicts, std::vector<DiskVerdict>{DiskVerdict::kFacing});
  EXPECT_EQ(r.stats.rejected_facing, 1u);
  EXPECT_EQ(rejections(r.stats), 1u);
}

TEST(DiskTest, ADiskThickerThanEpsilonIsNotFlat) {
  // Its centre 0.8 above its corners; the slab along the mean normal (z) is 0.8 thick.
  const Surface s = square_fan(1.8f);
  EXPECT_EQ(s.test(kBox2, 0.5).verdicts, std::vector<DiskVerdict>{DiskVerdict::kFlatness});
  EXPECT_EQ(s.test(kBox2, 0.5).stats.rejected_flatness, 1u);
  // Within a larger epsilon it passes.
  EXPECT_EQ(s.test(kBox2, 0.9).verdicts, std::vector<DiskVerdict>{DiskVerdict::kDisk});
}

TEST(DiskTest, TwoComponentsThatNoSlabSeparatesStay) {
  // A: a twisted strip across the corner edge x = 0, y = 0 (its slab about x + y − 0.2 z ∈
  // [0.4, 0.6]); B: a triangle in the top face between A and that edge, one vertex inside A's
  // slab, while A has vertices in B's plane (z = 2). They do not meet; neither slab parts them.
  Surface s;
  const VertexId p1 = s.vertex(0.5f, 0, 0), p2 = s.vertex(0, 0.5f, 0), p3 = s.vertex(0, 1, 2),
                 p4 = s.vertex(0.8f, 0, 2);
  s.triangle(p1, p4, p3);
  s.triangle(p1, p3, p2);
  s.triangle(s.vertex(0.2f, 0.1f, 2), s.vertex(0.1f, 0.2f, 2), s.vertex(0.3f, 0.6f, 2));
  const auto r = s.test(kBox2, 0.5);
  EXPECT_FALSE(r.all);
  EXPECT_EQ(r.verdicts, (std::vector<DiskVerdict>{DiskVerdict::kSeparation,
                                                  DiskVerdict::kSeparation}));
  EXPECT_EQ(r.stats.rejected_separation, 2u);
  EXPECT_EQ(rejections(r.stats), 2u);
  EXPECT_EQ(r.kept.size(), 3u);
}

TEST(DiskTest, ADiskWhoseLoopFoldsBackInProjectionHasNoSimpleOutline) {
  // The square cut by a slit from the middle of its front edge to its centre, the slit in
  // the top face (z = 1) and the corners lower (z = 0.5); the slit's two sides are distinct
  // vertices m1, m2 at one position. Topologically a disk, every triangle faces up and it is
  // flat within 1, but projected its loop runs up the slit and back down it.
  //   c3 ------- c2
  //   |  \     / |
  //   |    t     |
  //   |  / | \   |
  //   c0 - m1m2 - c1
  Surface s;
  const VertexId c0 = s.vertex(0, 0, 0.5f), c1 = s.vertex(2, 0, 0.5f), c2 = s.vertex(2, 2, 0.5f),
                 c3 = s.vertex(0, 2, 0.5f), m1 = s.vertex(1, 0, 1), m2 = s.vertex(1, 0, 1),
                 t = s.vertex(1, 1, 1);
  s.triangle(m2, c1, t);
  s.triangle(c1, c2, t);
  s.triangle(t, c2, c3);
  s.triangle(c3, c0, t);
  s.triangle(c0, m1, t);
  const Box box{{0, 0, 0}, {2, 2, 1}};
  const auto r = s.test(box, 1.0);
  EXPECT_FALSE(r.all);
  EXPECT_EQ(r.verdicts, std::vector<DiskVerdict>{DiskVerdict::kOutline});
  EXPECT_EQ(r.stats.rejected_outline, 1u);
  EXPECT_EQ(rejections(r.stats), 1u);
  EXPECT_EQ(r.kept.size(), 5u);
}

// test_one_piece, on surfaces of one piece, gives test_triangles' verdict and records the
// same disk or keeps the same triangles; a rejection is counted once, for one reason.
TEST(DiskTest, OnePieceTestGivesTheFullTestsResult) {
  Surface tilted = square_fan(1.2f);  // a disk whose normal is not an axis
  tilted.positions[2][2] = 1.3f;
  struct Case {
    const char* name;
    Surface surface;
    double epsilon;
    bool passes;
  };
  const std::vector<Case> cases{{"flat", square_fan(1.0f), 0.5, true},
                                {"tilted", tilted, 0.5, true},
                                {"thick", square_fan(1.8f), 0.5, false},
                                {"thick within 0.9", square_fan(1.8f), 0.9, true},
                                {"pinched (one piece)", pinched_corners(), 0.5, false},
                                {"shell (one piece)", tetrahedron(), 0.5, false}};
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    const auto full = k.surface.test(kBox2, k.epsilon);
    const auto one = k.surface.test(kBox2, k.epsilon, /*one_piece=*/true);
    EXPECT_EQ(one.all, k.passes);
    EXPECT_EQ(full.all, k.passes);
    EXPECT_EQ(rejections(one.stats), k.passes ? 0u : 1u);
    EXPECT_EQ(one.kept, full.kept);
    ASSERT_EQ(one.store.disks.size(), full.store.disks.size());
    EXPECT_EQ(one.store.loops, full.store.loops);
    EXPECT_EQ(one.store.triangles, full.store.triangles);
    EXPECT_EQ(one.store.areas, full.store.areas);
    EXPECT_EQ(one.store.vertices, full.store.vertices);
    for (std::size_t i = 0; i < one.store.disks.size(); ++i) {
      EXPECT_EQ(one.store.disks[i].normal, full.store.disks[i].normal);
      EXPECT_EQ(one.store.disks[i].area, full.store.disks[i].area);
      EXPECT_EQ(one.store.disks[i].band, full.store.disks[i].band);
    }
  }
}

}  // namespace
}  // namespace typemerge::core::merge
