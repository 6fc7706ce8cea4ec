// conversion_memory_estimate: int16 samples take 2 bytes a voxel off the volume's 4, nothing
// else changes.
#include <gtest/gtest.h>

#include <cstdint>

#include "app/memory_budget.h"

namespace typemerge::app {
namespace {

TEST(MemoryBudget, Int16SamplesSaveTwoBytesAVoxel) {
  constexpr std::uint64_t kVoxels = 100'000'000;
  ConversionShape float_shape;
  ConversionShape int16_shape;
  int16_shape.int16_samples = true;
  const double saved = double(conversion_memory_estimate(kVoxels, float_shape)) -
                       double(conversion_memory_estimate(kVoxels, int16_shape));
  EXPECT_NEAR(saved, 1.1 * 2.0 * double(kVoxels), 2.0);
  // The fixed part is the same: an empty grid costs the same either way.
  EXPECT_EQ(conversion_memory_estimate(0, float_shape), conversion_memory_estimate(0, int16_shape));
  // Still above what convert --preset bone --threads 2 was measured to hold with int16 samples
  // (2.19–2.95 bytes a voxel besides the mesh on 79–315 M voxels; docs/benchmarks.md).
  EXPECT_GT(double(conversion_memory_estimate(kVoxels, int16_shape)), 3.0 * double(kVoxels));
}

}  // namespace
}  // namespace typemerge::app
