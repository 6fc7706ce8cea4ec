#include "seg/frame_grid.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace typemerge::seg {
namespace {

std::string mm(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value << " mm";
  return out.str();
}

// Places every frame on a grid of `step` starting at `first`; the first misfit's message
// when a frame is off the grid or the grid is too long.
std::string try_step(std::span<const double> distances, double first, double last, double step,
                     std::int64_t max_slices, FramePlacement& placement) {
  const double span_steps = (last - first) / step;
  if (!(span_steps < static_cast<double>(max_slices))) {
    return "a " + mm(step) + " slice step over " + mm(last - first) + " makes more than " +
           std::to_string(max_slices) + " slices";
  }
  placement.slice_of_frame.assign(distances.size(), 0);
  for (std::size_t f = 0; f < distances.size(); ++f) {
    const double steps = (distances[f] - first) / step;
    const double nearest = std::round(steps);
    if (std::abs(steps - nearest) > kGridTolerance) {
      std::ostringstream out;
      out.precision(3);
      out << "frame " << f + 1 << " lies " << std::abs(steps - nearest)
          << " steps off the " << mm(step) << " slice grid";
      return out.str();
    }
    placement.slice_of_frame[f] = static_cast<std::int64_t>(nearest);
  }
  placement.slices = static_cast<std::int64_t>(std::round(span_steps)) + 1;
  placement.first_mm = first;
  placement.step_mm = step;
  return {};
}

}  // namespace

FramePlacement place_frames(std::span<const double> distances,
                            std::optional<double> spacing_between_slices,
                            double single_slice_step, std::int64_t max_slices) {
  FramePlacement placement;
  if (distances.empty()) {
    placement.error = "no frames";
    return placement;
  }
  std::vector<double> sorted(distances.begin(), distances.end());
  std::sort(sorted.begin(), sorted.end());
  const double first = sorted.front();
  const double last = sorted.back();
  if (last - first <= kSamePositionMm) {
    placement.slice_of_frame.assign(distances.size(), 0);
    placement.slices = 1;
    placement.first_mm = first;
    placement.step_mm = single_slice_step;
    return placement;
  }
  std::optional<double> smallest;
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    const double gap = sorted[i] - sorted[i - 1];
    if (gap > kSamePositionMm && (!smallest || gap < *smallest)) smallest = gap;
  }

  if (!smallest) {
    placement.error = "the frames' positions are too close together to tell slices apart";
    return placement;
  }
  std::string misfit;
  if (spacing_between_slices) {
    // The file's spacing is authoritative: a finer grid inferred from misfit frames would put
    // empty slices between every pair of real ones.
    if (!(*spacing_between_slices > kSamePositionMm) || !std::isfinite(*spacing_between_slices)) {
      placement.error = "Spacing Between Slices " + mm(*spacing_between_slices) + " is not usable";
      return placement;
    }
    misfit = try_step(distances, first, last, *spacing_between_slices, max_slices, placement);
  } else {
    misfit = try_step(distances, first, last, *smallest, max_slices, placement);
  }
  if (misfit.empty()) return placement;
  placement = FramePlacement{};
  placement.error = "the frames fit no slice grid: " + misfit;
  return placement;
}

}  // namespace typemerge::seg
