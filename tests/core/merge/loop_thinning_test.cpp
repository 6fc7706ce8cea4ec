// Loop thinning (core/merge/loop_thinning.h) on hand-made face polylines: the Douglas–Peucker
// bound both ways, the vertices it must keep, and the lattice-line rule.
#include "core/merge/loop_thinning.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/mesh_distance.h"

namespace typemerge::core::merge {
namespace {

// Distance from p to the polyline through positions[ids[k]] for the kept ids.
double distance_to_polyline(const P3& p, const std::vector<Position>& positions,
                            const std::vector<VertexId>& ids) {
  double best = INFINITY;
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
    best = std::min(best, std::sqrt(detail::point_segment_distance_squared(
                              p, to_double(positions[ids[k]]), to_double(positions[ids[k + 1]]))));
  }
  return best;
}

// The largest distance from points sampled along polyline a (every 1/100 of each segment)
// to polyline b.
double one_sided(const std::vector<Position>& positions, const std::vector<VertexId>& a,
                 const std::vector<VertexId>& b) {
  double worst = 0;
  for (std::size_t k = 0; k + 1 < a.size(); ++k) {
    const P3 p = to_double(positions[a[k]]);
    const P3 q = to_double(positions[a[k + 1]]);
    for (int s = 0; s <= 100; ++s) {
      const double t = s / 100.0;
      const P3 x{p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), p[2] + t * (q[2] - p[2])};
      worst = std::max(worst, distance_to_polyline(x, positions, b));
    }
  }
  return worst;
}

// A wavy polyline in the face x = 0 (off every lattice line but at its ends' own coordinates):
// y from 0.3 to 7.3, z = 0.5 + 0.15 sin(1.7 k), and one spike of 0.9 at k = 9.
std::vector<Position> wavy_face_polyline() {
  std::vector<Position> p;
  for (int k = 0; k <= 14; ++k) {
    const double z = 0.5 + 0.15 * std::sin(1.7 * k) + (k == 9 ? 0.9 : 0.0);
    p.push_back({0.0f, static_cast<float>(0.3 + 0.5 * k), static_cast<float>(z)});
  }
  return p;
}

TEST(LoopThinning, ThinnedPolylineStaysWithinTheToleranceBothWays) {
  const std::vector<Position> positions = wavy_face_polyline();
  std::vector<VertexId> run;
  for (VertexId v = 0; v < positions.size(); ++v) run.push_back(v);
  for (const double tolerance : {0.05, 0.2, 0.4}) {
    std::vector<std::uint8_t> state(positions.size(), kOpen);
    const std::size_t removed = thin_polyline(positions, run, tolerance, state);
    std::vector<VertexId> kept;
    for (VertexId v : run) {
      if (state[v] != kRemoved) kept.push_back(v);
    }
    EXPECT_EQ(kept.size() + removed, run.size());
    EXPECT_EQ(kept.front(), run.front());
    EXPECT_EQ(kept.back(), run.back());
    EXPECT_LE(one_sided(positions, run, kept), tolerance + 1e-9) << tolerance;
    EXPECT_LE(one_sided(positions, kept, run), tolerance + 1e-9) << tolerance;
    // The spike (0.9 above its neighbours' chord) is farther than any tolerance: it stays.
    EXPECT_NE(state[9], kRemoved) << tolerance;
    if (tolerance >= 0.2) {
      EXPECT_GT(removed, 5u) << tolerance;  // the waves (±0.15) go
    } else {
      EXPECT_LT(removed, 5u) << tolerance;
    }
  }
}

TEST(LoopThinning, NoShortcutAlongALatticeLine) {
  // Ends on the lattice line x = 0, y = 1 (along z); the middle vertex is 0.05 off it.
  const std::vector<Position> positions{{0, 1, 0.3f}, {0, 1.05f, 1.0f}, {0, 1, 1.7f}};
  EXPECT_TRUE(on_one_lattice_line(positions[0], positions[2]));
  EXPECT_FALSE(on_one_lattice_line(positions[0], positions[1]));
  std::vector<std::uint8_t> state(3, kOpen);
  const std::vector<VertexId> run{0, 1, 2};
  EXPECT_EQ(thin_polyline(positions, run, 0.5, state), 0u);
  EXPECT_EQ(state[1], kKept);
  // Off the lattice line (y = 1.5 is no lattice coordinate) the same shortcut is taken.
  const std::vector<Position> off{{0, 1.5f, 0.3f}, {0, 1.55f, 1.0f}, {0, 1.5f, 1.7f}};
  state.assign(3, kOpen);
  EXPECT_EQ(thin_polyline(off, run, 0.5, state), 1u);
  EXPECT_EQ(state[1], kRemoved);
}

TEST(LoopThinning, SharedFaceBetweenTwoDisksIsThinnedWithinEpsilon) {
  // Two flat disks (band 0) in the boxes [0,2]×[0,4]×[0,2] and [2,4]×[0,4]×[0,2], sharing the
  // face x = 2, their loops both running through the face's polyline p1..p5 (inside the face,
  // on no box edge). Each loop: the polyline and a return path on the outer faces.
  // The polyline's ends are not on one lattice line (z 0.9 and 1.1), its inner vertices within
  // 0.04 of the chord between them.
  std::vector<Position> positions{
      {2, 0, 0.9f},     {2, 0.7f, 0.965f}, {2, 1.4f, 0.93f}, {2, 2.1f, 1.045f},
      {2, 2.8f, 0.99f}, {2, 3.5f, 1.095f}, {2, 4, 1.1f},  // 0..6: on the shared face
      {0, 4, 1},        {0, 0, 1},                    // 7, 8: the left disk's far side
      {4, 4, 1},        {4, 0, 1}};                   // 9, 10: the right disk's far side
  DiskStore store;
  MergedDisk left;
  left.box = {{0, 0, 0}, {2, 4, 2}};
  left.loop_first = 0;
  left.loop_size = 9;
  store.loops = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  MergedDisk right;
  right.box = {{2, 0, 0}, {4, 4, 2}};
  right.loop_first = 9;
  right.loop_size = 9;
  for (VertexId v : {6, 5, 4, 3, 2, 1, 0, 10, 9}) store.loops.push_back(static_cast<VertexId>(v));
  store.disks = {left, right};
  LoopOwners::Arrays arrays;
  const LoopOwners owners(positions, store, arrays);
  EXPECT_EQ(owners.partner(3, 0), 1u);
  EXPECT_EQ(owners.partner(3, 1), 0u);
  EXPECT_EQ(owners.partner(7, 0), kNone);  // on the left disk's loop only
  EXPECT_EQ(owners.partner(0, 0), kNone);  // on both loops, but on the boxes' edge y = 0
  EXPECT_EQ(owners.partner(0, 1), kNone);
  {
    // A part added to the store after the table was made (as a split does): its partner at
    // vertex 3 is the first owner the table recorded, if its own box has 3 inside a face.
    DiskStore grown = store;
    LoopOwners::Arrays grown_arrays;
    const LoopOwners before_growth(positions, grown, grown_arrays);
    MergedDisk part;
    part.box = {{2, 0, 0}, {3, 4, 2}};  // vertex 3 inside its face x = 2
    grown.disks.push_back(part);
    EXPECT_EQ(before_growth.partner(3, 2), 0u);
    grown.disks[2].box = {{1, 0, 0}, {3, 4, 2}};  // vertex 3 inside the box, on no face
    EXPECT_EQ(before_growth.partner(3, 2), kNone);
  }
  std::vector<std::uint8_t> state(positions.size(), kOpen);
  MergeStats stats;
  thin_shared_faces(positions, store, owners, Tolerance::in_voxels(0.1), state, stats);
  // Within 0.1 all five inner
  // vertices go (both disks drop the same ones: the state is per vertex).
  EXPECT_EQ(stats.face_vertices_removed, 5u);
  for (VertexId v = 1; v <= 5; ++v) EXPECT_EQ(state[v], kRemoved) << v;
  EXPECT_NE(state[0], kRemoved);
  EXPECT_NE(state[6], kRemoved);
  // With a band of 0.099 on one disk, the tolerance sqrt(0.1² − 0.099²) ≈ 0.014 keeps some.
  store.disks[1].band = 0.099;
  state.assign(positions.size(), kOpen);
  MergeStats tight;
  thin_shared_faces(positions, store, owners, Tolerance::in_voxels(0.1), state, tight);
  EXPECT_LT(tight.face_vertices_removed, 5u);
}

}  // namespace
}  // namespace typemerge::core::merge
