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
