#include "preprocess/run_mask.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/union_find.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace typemerge::preprocess::runs {
namespace {

// Appends [begin, end) to a row being built in `out` (runs in increasing order), joining it
// to the last run when they overlap or touch.
void append(std::vector<Run>& out, std::size_t row_first, std::int32_t begin, std::int32_t end) {
  if (begin >= end) return;
  if (out.size() > row_first && out.back().end >= begin) {
    out.back().end = std::max(out.back().end, end);
  } else {
    out.push_back({begin, end});
  }
}

// The intersection of two rows (sorted, disjoint runs), appended to `out`.
void intersect_rows(const Run* a, const Run* a_end, const Run* b, const Run* b_end,
                    std::vector<Run>& out) {
  while (a != a_end && b != b_end) {
    const std::int32_t begin = std::max(a->begin, b->begin);
    const std::int32_t end = std::min(a->end, b->end);
    if (begin < end) out.push_back({begin, end});
    if (a->end < b->end) {
      ++a;
    } else {
      ++b;
    }
  }
}

// The union of two rows, appended to `out` (a row of its own, starting at out.size()).
void unite_rows(const Run* a, const Run* a_end, const Run* b, const Run* b_end,
                std::vector<Run>& out) {
  const std::size_t first = out.size();
  while (a != a_end || b != b_end) {
    const Run* next = b == b_end || (a != a_end && a->begin <= b->begin) ? a++ : b++;
    append(out, first, next->begin, next->end);
  }
}

}  // namespace

std::uint64_t SliceRuns::count() const {
  std::uint64_t n = 0;
  for (const Run& r : runs) n += static_cast<std::uint64_t>(r.end - r.begin);
  return n;
}

Kernel ellipse_kernel(int rx, int ry) {
  const cv::Mat element =
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
  Kernel kernel;
  for (int i = 0; i < element.rows; ++i) {
    const std::uint8_t* row = element.ptr<std::uint8_t>(i);
    int first = element.cols, last = -1;
    for (int j = 0; j < element.cols; ++j) {
      if (row[j] == 0) continue;
      first = std::min(first, j);
      last = j;
    }
    for (int j = first; j <= last; ++j) {
      if (row[j] == 0) throw std::logic_error("structuring element row is not one interval");
    }
    kernel.left.push_back(first - rx);
    kernel.right.push_back(last - rx);
  }
  return kernel;
}

namespace {

SliceRuns empty_rows(std::int32_t cols, std::int32_t rows) {
  SliceRuns out;
  out.cols = cols;
  out.row_start.assign(static_cast<std::size_t>(rows) + 1, 0);
  return out;
}

SliceRuns all_rows(std::int32_t cols, std::int32_t rows) {
  SliceRuns out;
  out.cols = cols;
  out.row_start.reserve(static_cast<std::size_t>(rows) + 1);
  for (std::int32_t y = 0; y < rows; ++y) {
    if (cols > 0) out.runs.push_back({0, cols});
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

// The runs of samples above `t` in columns [x, end) of a row, one sample at a time, carrying
// the state (`inside`: a run open since `begin`); a run still open at `end` is left open.
template <typename Sample, typename Threshold>
void scan_columns(const Sample* row, std::int32_t x, std::int32_t end, Threshold t, bool& inside,
                  std::int32_t& begin, std::vector<Run>& runs) {
  for (; x < end; ++x) {
    const bool now = row[x] > t;
    if (now == inside) continue;
    if (now) {
      begin = x;
    } else {
      runs.push_back({begin, x});
    }
    inside = now;
  }
}

}  // namespace

SliceRuns threshold_above(const float* values, std::int32_t cols, std::int32_t rows,
                          float threshold) {
  SliceRuns out;
  out.cols = cols;
  out.row_start.reserve(static_cast<std::size_t>(rows) + 1);
  for (std::int32_t y = 0; y < rows; ++y) {
    const float* row = values + static_cast<std::ptrdiff_t>(y) * cols;
    bool inside = false;
    std::int32_t begin = 0;
    std::int32_t x = 0;
    // Blocks of 16 that are all on the current side are skipped at once (most of a row is
    // air or tissue); the comparisons of a block vectorise.
    constexpr std::int32_t kBlock = 16;
    while (x < cols) {
      if (x + kBlock <= cols) {
        int above = 0;
        for (std::int32_t i = 0; i < kBlock; ++i) above += row[x + i] > threshold ? 1 : 0;
        if (above == (inside ? kBlock : 0)) {
          x += kBlock;
          continue;
        }
      }
      const std::int32_t stop = std::min(cols, x + kBlock);
      scan_columns(row, x, stop, threshold, inside, begin, out.runs);
      x = stop;
    }
    if (inside) out.runs.push_back({begin, cols});
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

// An integer v is above a float t exactly when it is above floor(t), so int16 samples are
// compared in int16. With SSE2, 16 samples at a time into a bit mask whose changes of bit are
// the runs' ends (a whole-body conversion thresholds each slice twice: the float route, which
// compilers leave scalar for int16, was about 7 % of a bone conversion's CPU, perf).
SliceRuns threshold_above(const std::int16_t* values, std::int32_t cols, std::int32_t rows,
                          float threshold) {
  if (!(threshold < 32767.0f)) return empty_rows(cols, rows);  // NaN too: nothing is above
  if (threshold < -32768.0f) return all_rows(cols, rows);
  const auto t = static_cast<std::int16_t>(std::floor(threshold));
  SliceRuns out;
  out.cols = cols;
  out.row_start.reserve(static_cast<std::size_t>(rows) + 1);
#if defined(__SSE2__)
  const __m128i wide_t = _mm_set1_epi16(t);
#endif
  for (std::int32_t y = 0; y < rows; ++y) {
    const std::int16_t* row = values + static_cast<std::ptrdiff_t>(y) * cols;
    bool inside = false;
    std::int32_t begin = 0;
    std::int32_t x = 0;
#if defined(__SSE2__)
    constexpr std::int32_t kBlock = 16;
    for (; x + kBlock <= cols; x += kBlock) {
      const __m128i low = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + x));
      const __m128i high = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + x + 8));
      // Bit i: sample x + i is above t (the packed 0 / −1 words keep their sign as bytes).
      const auto above = static_cast<std::uint32_t>(_mm_movemask_epi8(
          _mm_packs_epi16(_mm_cmpgt_epi16(low, wide_t), _mm_cmpgt_epi16(high, wide_t))));
      // Bits that differ from the current side: each is the next run's start or end.
      std::uint32_t change = above ^ (inside ? 0xFFFFu : 0u);
      while (change != 0) {
        const auto i = static_cast<std::int32_t>(std::countr_zero(change));
        if (inside) {
          out.runs.push_back({begin, x + i});
        } else {
          begin = x + i;
        }
        inside = !inside;
        // The bits after i that differ from the new side.
        change = (above ^ (inside ? 0xFFFFu : 0u)) & (0xFFFFu << (i + 1));
      }
    }
#endif
    scan_columns(row, x, cols, t, inside, begin, out.runs);
    if (inside) out.runs.push_back({begin, cols});
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

SliceRuns erode(const SliceRuns& in, const Kernel& kernel) {
  SliceRuns out;
  out.cols = in.cols;
  const std::int32_t rows = in.rows();
  const std::int32_t half = kernel.half_rows();
  std::vector<Run> acc, shrunk, next;
  for (std::int32_t y = 0; y < rows; ++y) {
    // Outside the image counts as set (OpenCV's default border for erosion): rows beyond
    // it add no condition, and a run touching the left or right edge is not shrunk there.
    acc.assign(1, Run{0, in.cols});
    for (std::int32_t i = 0; i < static_cast<std::int32_t>(kernel.left.size()) && !acc.empty();
         ++i) {
      const std::int32_t source = y + i - half;
      if (source < 0 || source >= rows || kernel.left[i] > kernel.right[i]) continue;
      shrunk.clear();
      for (const Run* r = in.row_begin(source); r != in.row_end(source); ++r) {
        const std::int32_t begin = r->begin == 0 ? 0 : r->begin - kernel.left[i];
        const std::int32_t end = r->end == in.cols ? in.cols : r->end - kernel.right[i];
        if (begin < end) shrunk.push_back({begin, end});
      }
      next.clear();
      intersect_rows(acc.data(), acc.data() + acc.size(), shrunk.data(),
                     shrunk.data() + shrunk.size(), next);
      acc.swap(next);
    }
    out.runs.insert(out.runs.end(), acc.begin(), acc.end());
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

SliceRuns dilate(const SliceRuns& in, const Kernel& kernel) {
  SliceRuns out;
  out.cols = in.cols;
  const std::int32_t rows = in.rows();
  const std::int32_t half = kernel.half_rows();
  std::vector<Run> acc, grown, next;
  for (std::int32_t y = 0; y < rows; ++y) {
    // Outside the image counts as clear (OpenCV's default border for dilation).
    acc.clear();
    for (std::int32_t i = 0; i < static_cast<std::int32_t>(kernel.left.size()); ++i) {
      const std::int32_t source = y + i - half;
      if (source < 0 || source >= rows || kernel.left[i] > kernel.right[i]) continue;
      if (in.row_begin(source) == in.row_end(source)) continue;
      grown.clear();
      for (const Run* r = in.row_begin(source); r != in.row_end(source); ++r) {
        append(grown, 0, std::max(0, r->begin - kernel.right[i]),
               std::min(in.cols, r->end - kernel.left[i]));
      }
      next.clear();
      unite_rows(acc.data(), acc.data() + acc.size(), grown.data(), grown.data() + grown.size(),
                 next);
      acc.swap(next);
    }
    out.runs.insert(out.runs.end(), acc.begin(), acc.end());
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

namespace {

// The difference of two rows (a without b), appended to `out`.
void subtract_rows(const Run* a, const Run* a_end, const Run* b, const Run* b_end,
                   std::vector<Run>& out) {
  for (const Run* r = a; r != a_end; ++r) {
    std::int32_t begin = r->begin;
    while (b != b_end && b->end <= begin) ++b;
    // Cuts that start before the run's end split it; the last may reach into the next run.
    for (const Run* c = b; c != b_end && c->begin < r->end; ++c) {
      if (c->begin > begin) out.push_back({begin, c->begin});
      begin = std::max(begin, c->end);
    }
    if (begin < r->end) out.push_back({begin, r->end});
  }
}

// Slice a op b, row by row.
template <typename RowOp>
SliceRuns combine(const SliceRuns& a, const SliceRuns& b, RowOp row_op) {
  SliceRuns out;
  out.cols = a.cols;
  for (std::int32_t y = 0; y < a.rows(); ++y) {
    row_op(a.row_begin(y), a.row_end(y), b.row_begin(y), b.row_end(y), out.runs);
    out.row_start.push_back(static_cast<std::uint32_t>(out.runs.size()));
  }
  return out;
}

}  // namespace

SliceRuns unite(const SliceRuns& a, const SliceRuns& b) { return combine(a, b, unite_rows); }

SliceRuns intersect(const SliceRuns& a, const SliceRuns& b) {
  return combine(a, b, intersect_rows);
}

SliceRuns subtract(const SliceRuns& a, const SliceRuns& b) {
  return combine(a, b, subtract_rows);
}

std::size_t keep_largest_component(std::vector<SliceRuns>& slices) {
  // Runs are numbered slice after slice, row after row: the order in which an image scan
  // meets them, so the smallest number of a component is where it is first met.
  std::vector<std::uint32_t> first(slices.size() + 1, 0);
  for (std::size_t k = 0; k < slices.size(); ++k) {
    first[k + 1] = first[k] + static_cast<std::uint32_t>(slices[k].runs.size());
  }
  if (first.back() == 0) return 0;
  std::vector<std::uint32_t> parent(first.back());
  std::iota(parent.begin(), parent.end(), 0u);
  auto join = [&](std::uint32_t a, std::uint32_t b) {
    a = core::find_root(parent, a);
    b = core::find_root(parent, b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  // Overlapping runs of two rows are 4-connected in the plane, or 6-connected across slices.
  auto join_rows = [&](const SliceRuns& s, std::uint32_t s_first, std::int32_t sy,
                       const SliceRuns& t, std::uint32_t t_first, std::int32_t ty) {
    std::uint32_t i = s.row_start[sy], i_end = s.row_start[sy + 1];
    std::uint32_t j = t.row_start[ty], j_end = t.row_start[ty + 1];
    while (i < i_end && j < j_end) {
      const Run& a = s.runs[i];
      const Run& b = t.runs[j];
      if (a.begin < b.end && b.begin < a.end) join(s_first + i, t_first + j);
      if (a.end < b.end) {
        ++i;
      } else {
        ++j;
      }
    }
  };
  for (std::size_t k = 0; k < slices.size(); ++k) {
    const SliceRuns& s = slices[k];
    for (std::int32_t y = 0; y + 1 < s.rows(); ++y) join_rows(s, first[k], y, s, first[k], y + 1);
    if (k + 1 < slices.size()) {
      for (std::int32_t y = 0; y < s.rows(); ++y) {
        join_rows(s, first[k], y, slices[k + 1], first[k + 1], y);
      }
    }
  }
  std::vector<std::uint64_t> size(parent.size(), 0);
  std::size_t components = 0;
  for (std::size_t k = 0; k < slices.size(); ++k) {
    for (std::size_t r = 0; r < slices[k].runs.size(); ++r) {
      const auto id = static_cast<std::uint32_t>(first[k] + r);
      const std::uint32_t root = core::find_root(parent, id);
      if (root == id) ++components;
      size[root] += static_cast<std::uint64_t>(slices[k].runs[r].end - slices[k].runs[r].begin);
    }
  }
  std::uint32_t best = 0;
  for (std::uint32_t g = 1; g < size.size(); ++g) {
    if (size[g] > size[best]) best = g;
  }
  for (std::size_t k = 0; k < slices.size(); ++k) {
    SliceRuns& s = slices[k];
    std::uint32_t kept = 0;
    std::uint32_t r = 0;
    for (std::int32_t y = 0; y < s.rows(); ++y) {
      const std::uint32_t end = s.row_start[y + 1];
      s.row_start[y] = kept;
      for (; r < end; ++r) {
        if (core::find_root(parent, first[k] + r) == best) s.runs[kept++] = s.runs[r];
      }
    }
    s.row_start.back() = kept;
    s.runs.resize(kept);
  }
  return components;
}

}  // namespace typemerge::preprocess::runs
