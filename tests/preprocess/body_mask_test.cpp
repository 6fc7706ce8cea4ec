#include "preprocess/body_mask.h"

#include <gtest/gtest.h>

#include <cmath>

namespace typemerge::preprocess {
namespace {

// A body (soft-tissue cylinder along z, with a bone rod inside) lying on a thin table top that
// touches it along a line, plus two metal rails under the table: in every slice
//
//        .-""-.        body: radius 20 mm, 40 HU, rod 1000 HU
//       (  ()  )
//        '-..-'
//   ==============     table top: 3 mm thick, 300 HU, touching the body
//     ||      ||       rails: 1500 HU
core::Volume body_on_table() {
  core::IndexToPatient geometry;
  geometry.axes = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 2}}};
  core::Volume volume({80, 70, 12}, geometry);
  for (std::int64_t k = 0; k < 12; ++k) {
    for (std::int64_t j = 0; j < 70; ++j) {
      for (std::int64_t i = 0; i < 80; ++i) {
        const double x = double(i) - 40, y = double(j) - 30;
        float hu = -1000;
        if (x * x + y * y <= 400) hu = 40;
        if (x * x + y * y <= 16) hu = 1000;
        if (y >= 20 && y < 23 && std::abs(x) < 38) hu = 300;
        if (y >= 26 && y < 30 && (std::abs(x - 20) < 2 || std::abs(x + 20) < 2)) hu = 1500;
        volume.at(i, j, k) = hu;
      }
    }
  }
  return volume;
}

TEST(BodyMask, ClearsTableAndRailsKeepsTheBody) {
  const core::Volume input = body_on_table();
  StepResult result = remove_outside_body(input);
  const core::Volume& out = result.volume;
  EXPECT_EQ(out.at(40, 30, 5), 1000.0f);      // the rod inside the body
  EXPECT_EQ(out.at(40 + 19, 30, 5), 40.0f);   // the body's edge
  EXPECT_EQ(input.at(5, 51, 5), 300.0f);      // the table top far from the body (y = 21 mm)
  EXPECT_EQ(out.at(5, 51, 5), -1000.0f);
  EXPECT_EQ(input.at(60, 57, 5), 1500.0f);    // a rail (x = 20, y = 27 mm)
  EXPECT_EQ(out.at(60, 57, 5), -1000.0f);
  // Every body voxel is kept.
  for (std::int64_t j = 0; j < 70; ++j) {
    for (std::int64_t i = 0; i < 80; ++i) {
      const double x = double(i) - 40, y = double(j) - 30;
      if (x * x + y * y <= 400) {
        ASSERT_EQ(out.at(i, j, 3), input.at(i, j, 3)) << i << "," << j;
      }
    }
  }
  ASSERT_NE(result.record.parameter("cleared_voxels"), nullptr);
  EXPECT_GT(std::stoi(*result.record.parameter("cleared_voxels")), 12 * 2 * 4 * 4);
}

// The abdomen series' case: a foam pad (here −400 HU, 6 mm thick) under the back, wider than
// the body, touching it along its whole width, and the table top under the pad.
TEST(BodyMask, ClearsAPadWiderThanTheBodyDownToAThinFringe) {
  core::Volume input = body_on_table();
  for (std::int64_t k = 0; k < 12; ++k) {
    for (std::int64_t j = 0; j < 70; ++j) {
      for (std::int64_t i = 0; i < 80; ++i) {
        const double x = double(i) - 40, y = double(j) - 30;
        if (y >= 14 && y < 20 && std::abs(x) < 38 && x * x + y * y > 400) input.at(i, j, k) = -400;
      }
    }
  }
  const StepResult result = remove_outside_body(input);
  const core::Volume& out = result.volume;
  EXPECT_EQ(out.at(40 + 30, 30 + 17, 5), -1000.0f);  // the pad beside the body
  EXPECT_EQ(out.at(40 - 30, 30 + 17, 5), -1000.0f);
  EXPECT_EQ(out.at(5, 51, 5), -1000.0f);              // the table top
  // What is left of the pad lies under the body: within the restore reach of the body (the
  // table top touching it counts as body there, like a nose would) plus the 2 mm edge.
  int pad = 0, left = 0;
  for (std::int64_t j = 0; j < 70; ++j) {
    for (std::int64_t i = 0; i < 80; ++i) {
      const double x = double(i) - 40, y = double(j) - 30;
      if (input.at(i, j, 5) == -400.0f) {
        ++pad;
        if (out.at(i, j, 5) == -400.0f) {
          ++left;
          EXPECT_LE(std::abs(x), 22.0) << i << "," << j;  // the pad reaches 38
        }
      }
      if (x * x + y * y <= 400) {
        ASSERT_EQ(out.at(i, j, 5), input.at(i, j, 5));
      }
    }
  }
  EXPECT_LT(left * 4, pad) << left << " of " << pad << " pad voxels left";
}

// The phantom_study case: a dry skull (a thin shell with air inside) on a solid holder. The
// opening breaks the shell, the holder becomes the largest component, and clearing the rest
// would delete the skull: the step must notice and leave the volume alone.
TEST(BodyMask, AThinShellOnAHolderIsLeftAloneWithAWarning) {
  core::IndexToPatient geometry;
  core::Volume input({80, 80, 40}, geometry);
  for (std::int64_t k = 0; k < 40; ++k) {
    for (std::int64_t j = 0; j < 80; ++j) {
      for (std::int64_t i = 0; i < 80; ++i) {
        const double r = std::hypot(double(i) - 40, double(j) - 30, double(k) - 20);
        float hu = -1000;
        if (r >= 16 && r < 19) hu = 1200;                     // the shell, 3 mm
        if (j >= 56 && j < 70 && i >= 20 && i < 60) hu = 60;  // the holder block
        input.at(i, j, k) = hu;
      }
    }
  }
  const StepResult result = remove_outside_body(input);
  EXPECT_EQ(result.volume.samples(), input.samples());
  ASSERT_EQ(result.record.warnings.size(), 1u);
  EXPECT_NE(result.record.warnings[0].find("table removal skipped"), std::string::npos);
}

TEST(BodyMask, EmptyVolumeIsReturnedWithAWarning) {
  core::Volume air({10, 10, 4}, {});
  for (float& v : air.samples()) v = -1000;
  const StepResult result = remove_outside_body(air);
  EXPECT_FALSE(result.record.warnings.empty());
  EXPECT_EQ(result.volume.samples(), air.samples());
  EXPECT_THROW(remove_outside_body(air, {.air_threshold_hu = -500, .opening_mm = 0}),
               std::invalid_argument);
}

}  // namespace
}  // namespace typemerge::preprocess
