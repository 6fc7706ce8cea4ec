// merge_piece with a recycled PieceScratch: a thread merges piece after piece in one scratch,
// smaller and larger ones in any order, and its last piece frees arrays early (keep false);
// every piece must come out as it does from a fresh scratch.
#include "core/merge/piece_merge.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "../test_volumes.h"
#include "core/marching_cubes.h"
#include "core/type_merging.h"

namespace typemerge::core::merge {
namespace {

// A bumpy body, in HU-like integers: bone (above 300) where the bumps are, soft tissue
// around; int16 when `int16`, else the same integers as floats.
Volume body(bool int16) {
  Volume volume = test::sample_volume(40, 36, 30, [](double x, double y, double z) {
    const double r = std::sqrt((x - 19.5) * (x - 19.5) + (y - 17.5) * (y - 17.5));
    const double bumps = 4.0 * std::sin(0.7 * x) * std::cos(0.5 * y) + 3.0 * std::sin(0.9 * z);
    return std::round(60.0 * (14.0 + bumps - r) + 0.5 * z * z);
  });
  if (!int16) return volume;
  Volume stored = Volume::uninitialized(volume.size(), volume.geometry(), SampleType::int16);
  for (std::size_t v = 0; v < volume.samples().size(); ++v) {
    stored.int16_samples()[v] = static_cast<std::int16_t>(volume.samples()[v]);
  }
  return stored;
}

void expect_same(const MergedPiece& a, const MergedPiece& b) {
  EXPECT_EQ(a.mesh.positions, b.mesh.positions);
  EXPECT_EQ(a.mesh.normals, b.mesh.normals);
  EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  EXPECT_EQ(a.shared, b.shared);
  EXPECT_EQ(a.top, b.top);
  EXPECT_EQ(a.stats.triangles_before, b.stats.triangles_before);
  EXPECT_EQ(a.stats.triangles_after, b.stats.triangles_after);
  EXPECT_EQ(a.stats.face_vertices_removed, b.stats.face_vertices_removed);
}

TEST(PieceMerge, RecycledScratchMergesEveryPieceAsAFreshOne) {
  for (const bool int16 : {false, true}) {
    for (const bool normals : {false, true}) {
      SCOPED_TRACE(testing::Message() << "int16 " << int16 << ", normals " << normals);
      const Volume volume = body(int16);
      ExtractOptions extract;
      extract.vertex_normals = normals;
      MergeOptions options;
      const std::int64_t layers = detail::cube_layer_count(volume, 300.0f, extract);
      ASSERT_GE(layers, 24);
      // Small, large, small, the padding slices at both ends: the scratch grows and shrinks.
      const std::vector<std::int64_t> bounds{0, 4, 20, 24, layers};
      PieceScratch recycled;
      std::size_t merged_triangles = 0;
      for (std::size_t i = 0; i + 1 < bounds.size(); ++i) {
        SCOPED_TRACE(testing::Message() << "piece " << i);
        PieceScratch fresh;
        const MergedPiece expected =
            merge_piece(volume, 300.0f, extract, options, bounds[i], bounds[i + 1], fresh);
        recycled.keep = i + 2 < bounds.size();  // the last piece frees arrays early
        const MergedPiece piece =
            merge_piece(volume, 300.0f, extract, options, bounds[i], bounds[i + 1], recycled);
        expect_same(piece, expected);
        merged_triangles += piece.mesh.triangles.size();
        // The piece's arrays, handed back as type_merging.cpp does with an appended piece's.
        recycled.output = piece.mesh;
      }
      EXPECT_GT(merged_triangles, 1000u);
    }
  }
}

TEST(PieceMerge, IntAndFloatSamplesGiveTheSamePieceWithPaddingSlices) {
  // close_borders pads the lattice with slices no array stores: both storages read them alike.
  const Volume floats = body(false);
  const Volume ints = body(true);
  ExtractOptions extract;
  ASSERT_TRUE(extract.close_borders);
  const std::int64_t layers = detail::cube_layer_count(floats, 300.0f, extract);
  PieceScratch a;
  PieceScratch b;
  expect_same(merge_piece(floats, 300.0f, extract, {}, 0, layers, a),
              merge_piece(ints, 300.0f, extract, {}, 0, layers, b));
}

}  // namespace
}  // namespace typemerge::core::merge
