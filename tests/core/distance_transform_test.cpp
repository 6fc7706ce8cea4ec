// The separable distance transform against brute force (every voxel against every seed, and
// the padding seeds beyond the border), on anisotropic grids.
#include "core/distance_transform.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace typemerge::core {
namespace {

constexpr float kFar = std::numeric_limits<float>::infinity();

std::vector<float> random_seeds(const VolumeSize& size, double share, unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution is_seed(share);
  std::vector<float> f(static_cast<std::size_t>(size.voxels()));
  for (float& v : f) v = is_seed(rng) ? 0.0f : kFar;
  return f;
}

// min over seeds of |p − q|², seeds being the zero samples and, with `border`, every lattice
// point of the one-layer padding.
std::vector<double> brute_force(const std::vector<float>& f, const VolumeSize& size,
                                const std::array<double, 3>& h, bool border) {
  std::vector<std::array<std::int64_t, 3>> seeds;
  for (std::int64_t k = -1; k <= size.nz; ++k) {
    for (std::int64_t j = -1; j <= size.ny; ++j) {
      for (std::int64_t i = -1; i <= size.nx; ++i) {
        const bool outside = i < 0 || j < 0 || k < 0 || i == size.nx || j == size.ny || k == size.nz;
        if (outside ? border : f[static_cast<std::size_t>(i + size.nx * (j + size.ny * k))] == 0) {
          seeds.push_back({i, j, k});
        }
      }
    }
  }
  std::vector<double> d(f.size(), std::numeric_limits<double>::infinity());
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 0; i < size.nx; ++i) {
        double& best = d[static_cast<std::size_t>(i + size.nx * (j + size.ny * k))];
        for (const auto& s : seeds) {
          const double dx = double(i - s[0]) * h[0], dy = double(j - s[1]) * h[1],
                       dz = double(k - s[2]) * h[2];
          best = std::min(best, dx * dx + dy * dy + dz * dz);
        }
      }
    }
  }
  return d;
}

// A slab of slices with a halo (inner_wall.cpp's use): where the nearest seed lies within the
// slab, the value is the whole grid's bit for bit; elsewhere it is no smaller. Slabs that
// start and end inside the grid, at its ends, and cover it whole; seeds sparse enough that
// many distances reach beyond a slab.
TEST(DistanceTransform, SlabMatchesTheWholeGridWhereItsNearestSeedIsInside) {
  const VolumeSize size{11, 9, 40};
  const std::array<double, 3> h{0.7, 0.9, 1.3};
  for (const bool border : {true, false}) {
    const std::vector<float> seeds = random_seeds(size, 0.004, border ? 5 : 6);
    std::vector<float> whole = seeds;
    squared_distance_transform(whole, size, h, border, 2);
    const std::vector<double> exact = brute_force(seeds, size, h, border);
    const auto plane = static_cast<std::size_t>(size.nx * size.ny);
    std::size_t equal = 0, beyond = 0;
    for (const auto& [first, count] : {std::pair<std::int64_t, std::int64_t>{0, 7}, {5, 9},
                                       {17, 23}, {31, 9}, {0, 40}}) {
      const VolumeSize slab{size.nx, size.ny, count};
      std::vector<float> part(seeds.begin() + static_cast<std::ptrdiff_t>(first * plane),
                              seeds.begin() + static_cast<std::ptrdiff_t>((first + count) * plane));
      squared_distance_transform_slab(part, slab, first, size.nz, h, border, 1);
      for (std::int64_t k = 0; k < count; ++k) {
        // Seeds beyond the slab are at least this far along z (the grid's end seeds count
        // only where the slab reaches the end).
        const double below = first == 0 ? 1e300 : double(k + 1) * h[2];
        const double above = first + count == size.nz ? 1e300 : double(count - k) * h[2];
        const double reach = std::min(below, above);
        for (std::size_t v = 0; v < plane; ++v) {
          const std::size_t at = static_cast<std::size_t>(k) * plane + v;
          const std::size_t global = static_cast<std::size_t>(first + k) * plane + v;
          if (exact[global] < reach * reach * (1 - 1e-9)) {
            ASSERT_EQ(part[at], whole[global]) << "slab at " << first << ", k " << k;
            ++equal;
          } else {
            ASSERT_GE(part[at], whole[global]);
            beyond += part[at] > whole[global] ? 1 : 0;
          }
        }
      }
    }
    EXPECT_GT(equal, 1000u);
    EXPECT_GT(beyond, 20u);  // the slabs did cut off seeds: the test tests something
  }
}

TEST(DistanceTransform, MatchesBruteForceOnAnisotropicGrids) {
  const VolumeSize size{13, 9, 7};
  for (const auto& h : {std::array<double, 3>{1, 1, 1}, std::array<double, 3>{0.7, 1.1, 2.5}}) {
    for (bool border : {false, true}) {
      for (double share : {0.02, 0.2}) {
        std::vector<float> f = random_seeds(size, share, 7);
        const auto expected = brute_force(f, size, h, border);
        squared_distance_transform(f, size, h, border, 2);
        for (std::size_t v = 0; v < f.size(); ++v) {
          if (std::isinf(expected[v])) {
            EXPECT_TRUE(std::isinf(f[v])) << v;
          } else {
            ASSERT_NEAR(f[v], expected[v], 1e-4 * (1 + expected[v]))
                << "voxel " << v << " spacing " << h[2] << " border " << border;
          }
        }
      }
    }
  }
}

TEST(DistanceTransform, NoSeedStaysInfiniteAndOneSeedGivesTheDistance) {
  const VolumeSize size{5, 4, 3};
  std::vector<float> f(60, kFar);
  squared_distance_transform(f, size, {1, 1, 1}, false, 1);
  for (float v : f) EXPECT_TRUE(std::isinf(v));
  f.assign(60, kFar);
  f[0] = 0;
  squared_distance_transform(f, size, {1, 2, 3}, false, 1);
  // Voxel (4, 3, 2): 4² + 6² + 6² = 88.
  EXPECT_FLOAT_EQ(f[4 + 5 * (3 + 4 * 2)], 88.0f);
}

}  // namespace
}  // namespace typemerge::core
