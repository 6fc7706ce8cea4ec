#include "core/distance_transform.h"

#include <cassert>
#include <cmath>
#include <cstddef>
#include <limits>

#include "core/parallel.h"

namespace typemerge::core {

namespace detail {

// The tight loop of Felzenszwalb & Huttenlocher's Algorithm 1 (DT1D), with positions in mm
// and only finite samples rooting parabolas (so no ∞ − ∞ in the intersections). Scratch
// layout: the finite samples' positions and values (x, g), the envelope's roots v (as indices
// into x, g) and its boundaries z.
void distance_transform_line(float* f, std::size_t count, std::ptrdiff_t step, double h,
                             bool border_seeds, std::vector<double>& scratch) {
  distance_transform_line(f, count, step, h, 0, border_seeds, border_seeds, scratch);
}

void distance_transform_line(float* f, std::size_t count, std::ptrdiff_t step, double h,
                             std::size_t offset, bool seed_before, bool seed_after,
                             std::vector<double>& scratch) {
  const std::size_t capacity = count + 2;
  scratch.resize(4 * capacity + 1);
  double* x = scratch.data();
  double* g = x + capacity;
  double* v = g + capacity;      // envelope roots (indices stored as doubles)
  double* z = v + capacity;      // capacity + 1 boundaries
  std::size_t n = 0;
  auto push = [&](double position, double value) {
    x[n] = position;
    g[n] = value;
    ++n;
  };
  // Positions on the whole line (offset + i), so that a part of it computes what the whole
  // line computes, bit for bit, wherever it finds the same nearest parabola.
  if (seed_before) push((static_cast<double>(offset) - 1.0) * h, 0.0);
  for (std::size_t i = 0; i < count; ++i) {
    const float value = f[static_cast<std::ptrdiff_t>(i) * step];
    if (std::isfinite(value)) push(static_cast<double>(offset + i) * h, value);
  }
  if (seed_after) push(static_cast<double>(offset + count) * h, 0.0);
  if (n == 0) return;  // no finite sample: everything stays +infinity

  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  std::size_t k = 0;  // index of the rightmost parabola in the envelope
  v[0] = 0;
  z[0] = -kInfinity;
  z[1] = kInfinity;
  for (std::size_t q = 1; q < n; ++q) {
    // Where the parabolas rooted at x[q] and x[r] meet (positions are distinct, so finite).
    auto meet = [&](std::size_t r) {
      return ((g[q] + x[q] * x[q]) - (g[r] + x[r] * x[r])) / (2 * (x[q] - x[r]));
    };
    double s = meet(static_cast<std::size_t>(v[k]));
    while (s <= z[k]) {  // z[0] = −∞ stops it
      --k;
      s = meet(static_cast<std::size_t>(v[k]));
    }
    ++k;
    v[k] = static_cast<double>(q);
    z[k] = s;
    z[k + 1] = kInfinity;
  }
  k = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const double position = static_cast<double>(offset + i) * h;
    while (z[k + 1] < position) ++k;
    const auto r = static_cast<std::size_t>(v[k]);
    const double d = position - x[r];
    f[static_cast<std::ptrdiff_t>(i) * step] = static_cast<float>(d * d + g[r]);
  }
}

}  // namespace detail

void squared_distance_transform(std::span<float> f, const VolumeSize& size,
                                const std::array<double, 3>& spacing, bool seeds_beyond_border,
                                unsigned threads) {
  squared_distance_transform_slab(f, size, 0, size.nz, spacing, seeds_beyond_border, threads);
}

void squared_distance_transform_slab(std::span<float> f, const VolumeSize& slab,
                                     std::int64_t first, std::int64_t total_slices,
                                     const std::array<double, 3>& spacing,
                                     bool seeds_beyond_border, unsigned threads) {
  assert(static_cast<std::int64_t>(f.size()) == slab.voxels());
  assert(first >= 0 && first + slab.nz <= total_slices);
  assert(spacing[0] > 0 && spacing[1] > 0 && spacing[2] > 0);
  if (slab.voxels() == 0) return;
  const unsigned workers = detail::resolve_threads(threads);
  std::vector<std::vector<double>> scratch(workers);
  const std::int64_t nx = slab.nx, ny = slab.ny, nz = slab.nz;
  // x lines: one per (j, k); y lines: one per (i, k), run slice by slice; z lines: one per (i, j).
  detail::run_parallel(static_cast<std::size_t>(ny * nz), workers, [&](std::size_t line, unsigned w) {
    detail::distance_transform_line(f.data() + line * static_cast<std::size_t>(nx),
                                    static_cast<std::size_t>(nx), 1, spacing[0],
                                    seeds_beyond_border, scratch[w]);
  });
  detail::run_parallel(static_cast<std::size_t>(nz), workers, [&](std::size_t k, unsigned w) {
    for (std::int64_t i = 0; i < nx; ++i) {
      detail::distance_transform_line(f.data() + k * static_cast<std::size_t>(nx * ny) +
                                          static_cast<std::size_t>(i),
                                      static_cast<std::size_t>(ny), nx, spacing[1],
                                      seeds_beyond_border, scratch[w]);
    }
  });
  // Along z the slab's own samples, and the grid's end seeds where the slab reaches an end.
  const bool seed_before = seeds_beyond_border && first == 0;
  const bool seed_after = seeds_beyond_border && first + nz == total_slices;
  detail::run_parallel(static_cast<std::size_t>(ny), workers, [&](std::size_t j, unsigned w) {
    for (std::int64_t i = 0; i < nx; ++i) {
      detail::distance_transform_line(f.data() + j * static_cast<std::size_t>(nx) +
                                          static_cast<std::size_t>(i),
                                      static_cast<std::size_t>(nz), nx * ny, spacing[2],
                                      static_cast<std::size_t>(first), seed_before, seed_after,
                                      scratch[w]);
    }
  });
}

}  // namespace typemerge::core
