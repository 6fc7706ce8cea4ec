// Tests of the window field and the "is the tissue there" test beside it.
#include "core/window_field.h"

#include <gtest/gtest.h>

namespace typemerge::core {
namespace {

Volume ramp(std::int64_t n) {
  Volume volume({n, n, n}, {});
  for (std::int64_t k = 0; k < n; ++k)
    for (std::int64_t j = 0; j < n; ++j)
      for (std::int64_t i = 0; i < n; ++i) volume.at(i, j, k) = float(i + j + k);
  return volume;
}

TEST(WindowField, IsTheDistanceToTheNearerBoundInsideTheWindow) {
  const Volume field = window_field(ramp(5), 3.0f, 7.0f);
  EXPECT_EQ(field.at(0, 0, 0), -3.0f);  // below lo
  EXPECT_EQ(field.at(1, 1, 1), 0.0f);   // on lo
  EXPECT_EQ(field.at(2, 1, 2), 2.0f);   // inside: min(5 − 3, 7 − 5)
  EXPECT_EQ(field.at(4, 4, 4), -5.0f);  // above hi
}

// From int16 samples with whole bounds the field is int16 (half the memory) with the same
// values; fractional bounds, or a sample farther than int16's range from both bounds, keep
// floats.
TEST(WindowField, Int16SamplesWithWholeBoundsGiveAnInt16Field) {
  Volume samples = ramp(5);
  samples.at(4, 4, 4) = 32767.0f;
  samples.at(0, 0, 0) = -32768.0f;
  ASSERT_TRUE(samples.to_int16_if_exact());
  const Volume whole = window_field(samples, -700.0f, 225.0f);
  EXPECT_TRUE(whole.holds_int16());
  EXPECT_EQ(whole.at(0, 0, 0), -32068.0f);  // −32768 − (−700)
  EXPECT_EQ(whole.at(4, 4, 4), -32542.0f);  // 225 − 32767
  EXPECT_EQ(whole.at(2, 1, 2), 220.0f);   // min(5 + 700, 225 − 5)
  const Volume fractional = window_field(samples, -700.5f, 225.0f);
  EXPECT_FALSE(fractional.holds_int16());
  EXPECT_EQ(fractional.at(0, 0, 0), -32067.5f);
  const Volume beyond = window_field(samples, 1000.0f, 2000.0f);  // −32768 − 1000 < −32768
  EXPECT_FALSE(beyond.holds_int16());
  EXPECT_EQ(beyond.at(0, 0, 0), -33768.0f);
  EXPECT_EQ(beyond.at(2, 1, 2), -995.0f);
  const Volume floats = window_field(ramp(5), 3.0f, 7.0f);
  EXPECT_FALSE(floats.holds_int16());
}

TEST(WindowField, CoverSaysWhetherTheWindowHoldsNoneSomeOrAllSamples) {
  const Volume volume = ramp(6);  // values 0 .. 15
  EXPECT_EQ(window_cover(volume, 20.0f, 30.0f), WindowCover::none);
  EXPECT_EQ(window_cover(volume, -5.0f, -1.0f), WindowCover::none);
  EXPECT_EQ(window_cover(volume, 15.0f, 15.0f), WindowCover::some);  // the last sample alone
  EXPECT_EQ(window_cover(volume, 0.0f, 0.0f), WindowCover::some);    // the first alone
  EXPECT_EQ(window_cover(volume, 0.0f, 15.0f), WindowCover::all);
  EXPECT_EQ(window_cover(Volume({1, 1, 1}, {}), 0.0f, 1.0f), WindowCover::all);
}

}  // namespace
}  // namespace typemerge::core
