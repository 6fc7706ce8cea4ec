// squared_distance_transform: the exact Euclidean distance transform of a sampled function on
// an anisotropic grid (Felzenszwalb & Huttenlocher 2012, "Distance Transforms of Sampled
// Functions", Theory of Computing 8), for `convert --hollow`'s inner wall (inner_wall.h).
//
// In place, every sample f(p) becomes min over samples q of |p − q|² + f(q), with |p − q| in
// mm along orthogonal axes of the given spacings. With f = 0 on seeds and +infinity elsewhere
// this is the squared distance to the nearest seed (+infinity when there is none). The 3D
// transform is three 1D passes (x, then y, then z), each the lower envelope of the parabolas
// rooted at the line's finite samples: O(n) per line. Written by hand rather than taken from
// OpenCV, whose cv::distanceTransform is 2D (one slice; slices do not see each other along z).
//
// `seeds_beyond_border`: every sample outside the grid counts as a seed (f = 0), as if the
// grid were padded by one layer of seeds — the marching cubes' closed borders, where
// everything outside the volume is outside.
//
// Memory: in place, plus a line's scratch (three arrays of n + 2) per thread. Lines run in
// parallel; the result does not depend on the thread count.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "core/volume.h"

namespace typemerge::core {

// Precondition: f.size() == size.voxels(); spacing > 0; no sample is NaN or −infinity.
void squared_distance_transform(std::span<float> f, const VolumeSize& size,
                                const std::array<double, 3>& spacing, bool seeds_beyond_border,
                                unsigned threads = 0);

// The same transform on a slab: f holds `slab.nz` slices, slices first … first + slab.nz − 1
// of a grid of `total_slices` (same nx, ny). Samples outside the slab are not seen; with
// seeds_beyond_border the grid's x and y borders are seeds, and its ends along z (slices −1
// and total_slices) where the slab reaches them. So every value is >= the whole grid's, and
// equal to it (the same arithmetic on the same positions, bit for bit, up to a tie between
// parabolas that floating point breaks otherwise) where the nearest seed lies in the slab —
// every sample whose squared distance is at most (mm along z to the slab's cut ends)², as
// seeds found in-plane first make the distance no larger. Memory: as above.
void squared_distance_transform_slab(std::span<float> f, const VolumeSize& slab,
                                     std::int64_t first, std::int64_t total_slices,
                                     const std::array<double, 3>& spacing,
                                     bool seeds_beyond_border, unsigned threads = 0);

namespace detail {
// One line of `count` samples `step` apart in f (in place), sample spacing h (mm); `scratch`
// is resized as needed. With `border_seeds`, seeds at positions −1 and count.
void distance_transform_line(float* f, std::size_t count, std::ptrdiff_t step, double h,
                             bool border_seeds, std::vector<double>& scratch);
// The same for samples offset … offset + count − 1 of a longer line (positions (offset + i)·h),
// with a seed at position offset − 1 and/or offset + count.
void distance_transform_line(float* f, std::size_t count, std::ptrdiff_t step, double h,
                             std::size_t offset, bool seed_before, bool seed_after,
                             std::vector<double>& scratch);
}  // namespace detail

}  // namespace typemerge::core
