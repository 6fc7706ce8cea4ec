#include <gtest/gtest.h>

#include <vector>

#include "seg/frame_grid.h"

namespace typemerge::seg {
namespace {

using Slices = std::vector<std::int64_t>;

TEST(FrameGrid, ShuffledFramesWithAGap) {
  const std::vector<double> distances = {10.0, 2.5, 7.5, 2.5};  // 5.0 missing
  const FramePlacement placed = place_frames(distances, std::nullopt, 1.0, 1000);
  ASSERT_TRUE(placed.ok()) << placed.error;
  EXPECT_EQ(placed.slice_of_frame, (Slices{3, 0, 2, 0}));
  EXPECT_EQ(placed.slices, 4);
  EXPECT_DOUBLE_EQ(placed.step_mm, 2.5);
  EXPECT_DOUBLE_EQ(placed.first_mm, 2.5);
}

TEST(FrameGrid, SpacingBetweenSlicesBridgesALargeGap) {
  // Only two frames 6 mm apart: the smallest step alone would make 2 slices.
  const std::vector<double> distances = {0.0, 6.0};
  const FramePlacement placed = place_frames(distances, 1.5, 1.0, 1000);
  ASSERT_TRUE(placed.ok());
  EXPECT_EQ(placed.slice_of_frame, (Slices{0, 4}));
  EXPECT_EQ(placed.slices, 5);
}

TEST(FrameGrid, JitterWithinTheTolerance) {
  const std::vector<double> distances = {0.0, 2.51, 4.98};
  const FramePlacement placed = place_frames(distances, 2.5, 1.0, 1000);
  ASSERT_TRUE(placed.ok());
  EXPECT_EQ(placed.slice_of_frame, (Slices{0, 1, 2}));
}

TEST(FrameGrid, OffTheGridIsRefused) {
  const std::vector<double> distances = {0.0, 2.5, 5.0, 6.0};
  const FramePlacement placed = place_frames(distances, 2.5, 1.0, 1000);
  EXPECT_FALSE(placed.ok());
  EXPECT_NE(placed.error.find("fit no slice grid"), std::string::npos) << placed.error;
  EXPECT_TRUE(placed.slice_of_frame.empty());
}

TEST(FrameGrid, TheGivenSpacingIsAuthoritative) {
  // These would fit a 1.25 mm grid, with an empty slice between every two real ones.
  const std::vector<double> distances = {0.0, 2.5, 3.75};
  EXPECT_FALSE(place_frames(distances, 2.5, 1.0, 1000).ok());
  const FramePlacement inferred = place_frames(distances, std::nullopt, 1.0, 1000);
  ASSERT_TRUE(inferred.ok());
  EXPECT_DOUBLE_EQ(inferred.step_mm, 1.25);
  EXPECT_EQ(inferred.slice_of_frame, (Slices{0, 2, 3}));
  EXPECT_FALSE(place_frames(distances, 0.0, 1.0, 1000).ok());
}

TEST(FrameGrid, OneSliceTakesTheGivenStep) {
  const std::vector<double> distances = {-3.0, -3.0, -3.001};
  const FramePlacement placed = place_frames(distances, std::nullopt, 2.0, 1000);
  ASSERT_TRUE(placed.ok());
  EXPECT_EQ(placed.slices, 1);
  EXPECT_DOUBLE_EQ(placed.step_mm, 2.0);
}

TEST(FrameGrid, TooManySlicesIsRefused) {
  const std::vector<double> distances = {0.0, 0.02, 1000.0};
  const FramePlacement placed = place_frames(distances, std::nullopt, 1.0, 1000);
  EXPECT_FALSE(placed.ok());
}

TEST(FrameGrid, PositionsCreepingApartInTinySteps) {
  const std::vector<double> distances = {0.0, 0.008, 0.016, 0.024};
  EXPECT_FALSE(place_frames(distances, std::nullopt, 1.0, 1000).ok());
}

TEST(FrameGrid, NoFrames) {
  EXPECT_FALSE(place_frames({}, std::nullopt, 1.0, 10).ok());
}

}  // namespace
}  // namespace typemerge::seg
