// Run-length masks of one slice, and the in-plane morphology and 3D components that table
// removal (body_mask) needs, on runs instead of bytes.
//
// Why by hand: OpenCV's morphology on byte masks reads every pixel once per kernel row, and
// table removal runs an elliptical opening and two dilations some mm wide on every slice: a
// large share of a whole-body conversion that way. A body slice is a few runs per row, so the
// same operations on runs cost per run, not per pixel (figures: docs/benchmarks.md, "Moved
// from headers and the README"). The results are
// exactly OpenCV's: the structuring elements are OpenCV's own (cv::getStructuringElement),
// read here as one centred interval per kernel row, and erosion treats outside the image as
// set, dilation as clear — OpenCV's default border for each.
#pragma once

#include <cstdint>
#include <vector>

namespace typemerge::preprocess::runs {

// Set pixels [begin, end) of one row.
struct Run {
  std::int32_t begin;
  std::int32_t end;
  bool operator==(const Run&) const = default;
};

// One slice: the runs of row y are runs[row_start[y], row_start[y + 1]), sorted, disjoint and
// not touching (two runs of a row always have a clear pixel between them).
struct SliceRuns {
  std::int32_t cols = 0;
  std::vector<Run> runs;
  std::vector<std::uint32_t> row_start{0};

  std::int32_t rows() const { return static_cast<std::int32_t>(row_start.size()) - 1; }
  const Run* row_begin(std::int32_t y) const { return runs.data() + row_start[y]; }
  const Run* row_end(std::int32_t y) const { return runs.data() + row_start[y + 1]; }
  std::uint64_t count() const;  // set pixels
};

// A structuring element as, per kernel row dy (from −rows/2 to rows/2), the offsets
// [left[i], right[i]] it covers (left > right: an empty row).
struct Kernel {
  std::vector<std::int32_t> left;
  std::vector<std::int32_t> right;
  std::int32_t half_rows() const { return static_cast<std::int32_t>(left.size()) / 2; }
};

// OpenCV's MORPH_ELLIPSE element of size (2 rx + 1) × (2 ry + 1), as a Kernel. Throws
// std::logic_error if a kernel row is not one interval (an ellipse's rows always are).
Kernel ellipse_kernel(int rx, int ry);

// The pixels with value > threshold of a rows × cols slice of floats or int16 samples (row
// after row; an int16 sample compares as the float of the same integer).
SliceRuns threshold_above(const float* values, std::int32_t cols, std::int32_t rows,
                          float threshold);
SliceRuns threshold_above(const std::int16_t* values, std::int32_t cols, std::int32_t rows,
                          float threshold);

// cv::erode / cv::dilate with the kernel (anchor at its centre) and OpenCV's default border.
SliceRuns erode(const SliceRuns& in, const Kernel& kernel);
SliceRuns dilate(const SliceRuns& in, const Kernel& kernel);

// Union, intersection and difference (a without b) of slices of the same size.
SliceRuns unite(const SliceRuns& a, const SliceRuns& b);
SliceRuns intersect(const SliceRuns& a, const SliceRuns& b);
SliceRuns subtract(const SliceRuns& a, const SliceRuns& b);

// Keeps, of the mask made of `slices` (slice after slice, all of one size), the largest
// 6-connected component (ties: the one met first in slice, row, column order); returns the
// number of components found (0: nothing set, the mask unchanged).
std::size_t keep_largest_component(std::vector<SliceRuns>& slices);

}  // namespace typemerge::preprocess::runs
