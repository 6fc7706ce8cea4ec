// Placing a SEG's frames on one slice grid from their distances along the slice normal.
//
// A SEG stores one frame per (segment, slice) that holds something; empty frames may be left
// out, and frames come in any order. The grid's step is the Spacing Between Slices when the
// file gives one, else the smallest step between distinct positions (distinct: more than
// kSamePositionMm apart). A frame fits a step s when its distance from the first slice is
// within kGridTolerance·s of a whole number of steps; it is placed on the nearest one. When a
// frame does not fit, the frames fit no grid and are refused (a finer grid that would fit
// them is not tried: it would put empty slices between every pair of real ones).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace typemerge::seg {

inline constexpr double kSamePositionMm = 0.01;
inline constexpr double kGridTolerance = 0.1;  // of a step

struct FramePlacement {
  std::vector<std::int64_t> slice_of_frame;  // one per input distance
  std::int64_t slices = 0;                   // from the lowest to the highest distance
  double first_mm = 0;                       // distance of slice 0 along the normal
  double step_mm = 0;                        // distance between slices
  std::string error;                         // set when the frames fit no grid (nothing else is)

  bool ok() const { return error.empty(); }
};

// `distances`: each frame's position · slice normal, mm (finite). `spacing_between_slices`:
// the file's, if any. `single_slice_step`: the step reported when all frames are on one slice.
// Refuses grids of more than `max_slices` slices.
FramePlacement place_frames(std::span<const double> distances,
                            std::optional<double> spacing_between_slices,
                            double single_slice_step, std::int64_t max_slices);

}  // namespace typemerge::seg
