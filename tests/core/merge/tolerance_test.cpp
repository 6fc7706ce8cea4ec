// Tolerance (core/merge/tolerance.h): what a slab and a thinned chord count against the bound,
// in voxels and in millimetres.
#include "core/merge/tolerance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace typemerge::core::merge {
namespace {

TEST(Tolerance, InVoxelsIsTodaysBound) {
  const Tolerance t = Tolerance::in_voxels(0.5);
  EXPECT_FALSE(t.in_mm());
  EXPECT_EQ(t.span(0.3, {0, 0, 1}), 0.3);
  EXPECT_EQ(t.thinning_tolerance(0.3, 0.1), std::sqrt(0.5 * 0.5 - 0.3 * 0.3));
  EXPECT_EQ(t.thinning_tolerance(0.6, 0.1), 0.0);
}

TEST(Tolerance, InMillimetresScalesASlabByTheStepAlongItsNormal) {
  const Tolerance t = Tolerance::in_mm(1.0, {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 3.0}}});
  EXPECT_TRUE(t.in_mm());
  EXPECT_DOUBLE_EQ(t.span(0.2, {0, 0, 1}), 0.6);   // 0.2 of a 3 mm step
  EXPECT_DOUBLE_EQ(t.span(0.2, {1, 0, 0}), 0.14);  // 0.2 of a 0.7 mm step
  const double s = std::sqrt(0.5);
  EXPECT_DOUBLE_EQ(t.span(1.0, {s, 0, s}), std::sqrt(0.5 * 0.49 + 0.5 * 9.0));
  // The offset across: (ε − the larger span) / the largest step, 3 mm.
  EXPECT_DOUBLE_EQ(t.thinning_tolerance(0.4, 0.1), 0.6 / 3.0);
  EXPECT_EQ(t.thinning_tolerance(1.2, 0.1), 0.0);
}

// On a sheared grid the stretch used for offsets bounds |A d| for every unit direction d.
TEST(Tolerance, OffsetsAreBoundedOnShearedGrids) {
  const std::array<P3, 3> axes{{{0.8, 0, 0}, {0, 0.8, 0}, {0, 0.9, 2.5}}};
  const Tolerance t = Tolerance::in_mm(2.0, axes);
  const double delta = t.thinning_tolerance(0.0, 0.0);  // = 2 / σ
  std::mt19937 rng(7);
  std::normal_distribution<double> g;
  for (int k = 0; k < 10000; ++k) {
    P3 d{g(rng), g(rng), g(rng)};
    const double length = std::sqrt(dot(d, d));
    for (double& x : d) x *= delta / length;
    P3 v{0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      for (int c = 0; c < 3; ++c) v[c] += d[a] * axes[a][c];
    }
    EXPECT_LE(std::sqrt(dot(v, v)), 2.0 + 1e-12);
  }
}

}  // namespace
}  // namespace typemerge::core::merge
