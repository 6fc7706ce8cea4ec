// core::Volume's two storages: when int16 holds the samples, and that the extractors give the
// same surface, bit for bit, from int16 samples as from the same values stored as floats.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>

#include "core/inner_wall.h"
#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/type_merging.h"
#include "core/volume.h"
#include "core/window_field.h"

namespace typemerge::core {
namespace {

TEST(FitsInt16, IntegersInRangeOnly) {
  EXPECT_TRUE(fits_int16(0.0));
  EXPECT_TRUE(fits_int16(-1000.0));
  EXPECT_TRUE(fits_int16(32767.0));
  EXPECT_TRUE(fits_int16(-32768.0));
  EXPECT_FALSE(fits_int16(32768.0));
  EXPECT_FALSE(fits_int16(-32769.0));
  EXPECT_FALSE(fits_int16(0.5));
  EXPECT_FALSE(fits_int16(-1000.25));
  EXPECT_FALSE(fits_int16(-0.0));  // would read back as +0
  EXPECT_FALSE(fits_int16(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_FALSE(fits_int16(std::numeric_limits<double>::infinity()));
  EXPECT_FALSE(fits_int16(1e12));
}

TEST(Int16Threshold, SameSideAsTheFloatComparison) {
  for (const float iso : {300.0f, 299.5f, -500.0f, -500.5f, 0.0f, -0.0f, 1e-7f, -1e-7f,
                          40000.0f, -40000.0f, 32767.5f, -32768.5f}) {
    const std::int32_t t = int16_threshold(iso);
    for (std::int32_t v = -32768; v <= 32767; v += 7) {
      ASSERT_EQ(static_cast<float>(v) >= iso, v >= t) << "iso " << iso << " v " << v;
    }
    for (const std::int32_t v : {-32768, 32767, -1, 0, 1}) {
      ASSERT_EQ(static_cast<float>(v) >= iso, v >= t) << "iso " << iso << " v " << v;
    }
  }
  EXPECT_EQ(int16_threshold(std::numeric_limits<float>::quiet_NaN()), 32768);
}

Volume integer_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz, unsigned seed) {
  // A smooth body (bone-like core, soft tissue, air outside) plus integer noise.
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-40, 40);
  Volume volume({nx, ny, nz}, IndexToPatient{});
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        const double x = double(i) - double(nx) / 2.0, y = double(j) - double(ny) / 2.0,
                     z = double(k) - double(nz) / 2.0;
        const double r = std::sqrt(x * x + y * y + 0.5 * z * z);
        const double value = r < 4 ? 700 : r < 9 ? 40 : -1000;
        volume.at(i, j, k) = static_cast<float>(std::lround(value) + noise(rng));
      }
    }
  }
  return volume;
}

TEST(VolumeStorage, ConvertsOnlyExactValues) {
  Volume volume = integer_volume(6, 5, 4, 1);
  Volume copy = volume;
  ASSERT_TRUE(copy.to_int16_if_exact());
  EXPECT_TRUE(copy.holds_int16());
  EXPECT_EQ(copy.sample_type(), SampleType::int16);
  EXPECT_EQ(copy.sample_bytes(), 6u * 5u * 4u * 2u);
  for (std::int64_t k = 0; k < 4; ++k) {
    for (std::int64_t j = 0; j < 5; ++j) {
      for (std::int64_t i = 0; i < 6; ++i) {
        EXPECT_EQ(std::as_const(copy).at(i, j, k), volume.at(i, j, k));
      }
    }
  }
  // Float views refuse int16 storage; int16 views refuse float storage.
  EXPECT_THROW((void)copy.samples(), std::logic_error);
  EXPECT_THROW((void)copy.slice(0), std::logic_error);
  EXPECT_THROW((void)volume.int16_samples(), std::logic_error);
  copy.to_float();
  EXPECT_FALSE(copy.holds_int16());
  EXPECT_EQ(copy.samples(), volume.samples());

  Volume fractional = volume;
  fractional.at(1, 1, 1) = 0.5f;
  EXPECT_FALSE(fractional.to_int16_if_exact());
  EXPECT_FALSE(fractional.holds_int16());
  EXPECT_EQ(fractional.at(1, 1, 1), 0.5f);
  Volume large = volume;
  large.at(0, 0, 0) = 40000.0f;
  EXPECT_FALSE(large.to_int16_if_exact());

  const Volume int16 = Volume::uninitialized({3, 2, 1}, IndexToPatient{}, SampleType::int16);
  EXPECT_TRUE(int16.holds_int16());
  EXPECT_EQ(int16.int16_samples().size(), 6u);
}

void expect_same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  ASSERT_EQ(a.normals.size(), b.normals.size());
  EXPECT_TRUE(a.positions == b.positions);  // exact float equality, vertex by vertex
  EXPECT_TRUE(a.normals == b.normals);
  EXPECT_TRUE(a.triangles == b.triangles);
}

// Every extractor, on the same values stored both ways, at integral and fractional isos and
// on one and two threads.
TEST(VolumeStorage, ExtractionFromInt16EqualsExtractionFromFloat) {
  const Volume as_float = integer_volume(40, 36, 30, 7);
  Volume as_int16 = as_float;
  ASSERT_TRUE(as_int16.to_int16_if_exact());
  for (const float iso : {300.0f, 299.5f, 40.0f, -500.0f}) {
    for (const unsigned threads : {1u, 2u}) {
      SCOPED_TRACE(testing::Message() << "iso " << iso << ", threads " << threads);
      ExtractOptions extract;
      extract.threads = threads;
      AmbiguityStats stats_f, stats_i;
      std::vector<BoundaryCube> cubes_f, cubes_i;
      extract.stats = &stats_f;
      extract.cubes = &cubes_f;
      const TriangleMesh mc_f = extract_isosurface(as_float, iso, extract);
      extract.stats = &stats_i;
      extract.cubes = &cubes_i;
      const TriangleMesh mc_i = extract_isosurface(as_int16, iso, extract);
      ASSERT_FALSE(mc_f.triangles.empty());
      expect_same_mesh(mc_f, mc_i);
      EXPECT_EQ(stats_f.boundary_cubes, stats_i.boundary_cubes);
      EXPECT_EQ(cubes_f.size(), cubes_i.size());

      ExtractOptions merge_extract;
      merge_extract.threads = threads;
      MergeOptions merge;
      merge.slab_layers = 8;  // several pieces: their bounds are estimated from the samples
      const TriangleMesh tm_f = extract_type_merged(as_float, iso, merge_extract, merge);
      const TriangleMesh tm_i = extract_type_merged(as_int16, iso, merge_extract, merge);
      ASSERT_FALSE(tm_f.triangles.empty());
      expect_same_mesh(tm_f, tm_i);
    }
  }
  // Isos beyond every int16 sample: nothing inside (40000, or +infinity), everything inside
  // (−40000: the closed borders' box); both storages classify them alike.
  for (const float iso : {40000.0f, -40000.0f, std::numeric_limits<float>::infinity()}) {
    SCOPED_TRACE(testing::Message() << "iso " << iso);
    const TriangleMesh mc_f = extract_isosurface(as_float, iso);
    const TriangleMesh mc_i = extract_isosurface(as_int16, iso);
    EXPECT_EQ(mc_f.triangles.empty(), iso > 0.0f);
    expect_same_mesh(mc_f, mc_i);
    MergeOptions merge;
    merge.slab_layers = 8;
    expect_same_mesh(extract_type_merged(as_float, iso, {}, merge),
                     extract_type_merged(as_int16, iso, {}, merge));
  }
  // The window field reads either storage into the same values (kept as int16 from int16).
  const Volume field_f = window_field(as_float, 0.0f, 400.0f);
  const Volume field_i = window_field(as_int16, 0.0f, 400.0f);
  EXPECT_TRUE(field_i.holds_int16());
  Volume widened = field_i;
  widened.to_float();
  EXPECT_EQ(field_f.samples(), widened.samples());
  {
    MergeOptions merge;
    merge.slab_layers = 8;
    const TriangleMesh window_f = extract_type_merged(field_f, 0.0f, {}, merge);
    ASSERT_FALSE(window_f.triangles.empty());
    expect_same_mesh(window_f, extract_type_merged(field_i, 0.0f, {}, merge));
    expect_same_mesh(extract_isosurface(field_f, 0.0f), extract_isosurface(field_i, 0.0f));
  }
  EXPECT_EQ(window_cover(as_int16, 0.0f, 400.0f), window_cover(as_float, 0.0f, 400.0f));

  // The inner wall reads the field's samples too.
  ExtractOptions closed;
  closed.threads = 1;
  const TriangleMesh outer = extract_isosurface(as_float, 0.0f, closed);
  InnerWallOptions wall;
  wall.wall_mm = 1.5;
  wall.threads = 1;
  const TriangleMesh inner_f = extract_inner_wall(as_float, 0.0f, outer, wall);
  const TriangleMesh inner_i = extract_inner_wall(as_int16, 0.0f, outer, wall);
  ASSERT_FALSE(inner_f.triangles.empty());
  expect_same_mesh(inner_f, inner_i);
}

}  // namespace
// release_slices: the whole pages of slices [begin, end) read as zeros (Linux), the rest keep
// their values; out-of-range ends are clamped.
TEST(Volume, ReleasedSlicesReadAsZerosAndTheOthersStay) {
  for (const bool int16 : {false, true}) {
    SCOPED_TRACE(int16);
    Volume volume({128, 64, 10}, IndexToPatient{});
    for (std::int64_t k = 0; k < 10; ++k) {
      for (std::int64_t j = 0; j < 64; ++j) {
        for (std::int64_t i = 0; i < 128; ++i) volume.at(i, j, k) = static_cast<float>(k + 1);
      }
    }
    if (int16) {
      ASSERT_TRUE(volume.to_int16_if_exact());
    }
    const Volume& view = volume;
    volume.release_slices(-3, 0);  // nothing
    volume.release_slices(6, 4);   // nothing
    EXPECT_EQ(view.at(5, 5, 0), 1.0f);
    EXPECT_EQ(view.at(5, 5, 5), 6.0f);
    volume.release_slices(4, 8);
#if defined(__linux__)
    // Slices of 16 or 32 KiB: slices 5 and 6 lie on whole pages wherever the samples start.
    for (std::int64_t k = 5; k < 7; ++k) EXPECT_EQ(view.at(7, 30, k), 0.0f) << k;
#endif
    for (std::int64_t k : {0, 1, 2, 3, 8, 9}) {
      EXPECT_EQ(view.at(0, 0, k), static_cast<float>(k + 1)) << k;
      EXPECT_EQ(view.at(127, 63, k), static_cast<float>(k + 1)) << k;
    }
    volume.release_slices(-5, 1000);  // clamped to every slice
#if defined(__linux__)
    EXPECT_EQ(view.at(64, 32, 9), 0.0f);
    EXPECT_EQ(view.at(64, 32, 1), 0.0f);
#endif
  }
}

}  // namespace typemerge::core
