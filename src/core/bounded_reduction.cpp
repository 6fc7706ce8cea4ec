#include "core/bounded_reduction.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <utility>

#include "core/bounded_collapse.h"

namespace typemerge::core {

namespace {

constexpr std::size_t kMaxTries = 24;

struct Try {
  double bound = 0.0;
  TriangleMesh mesh;
  MergeStats stats;
};

// Marching cubes' surface of the volume in patient mm: what the collapses are judged against.
TriangleMesh reference_surface(const Volume& volume, float iso, const ExtractOptions& extract) {
  ExtractOptions silent = extract;
  silent.slices_done = nullptr;  // a reduction says it through MergeOptions::slices_done
  TriangleMesh reference = extract_isosurface(volume, iso, silent);
  to_patient(reference, volume.geometry());
  return reference;
}

CollapseStats collapse_against(const TriangleMesh& reference, const IndexToPatient& geometry,
                               TriangleMesh& merged, const CollapseOptions& options) {
  // The collapses judge distances, shapes and crossings in millimetres, on the floats
  // to_patient makes (the ones written); the triangles they leave are then taken back to the
  // index-space positions, undoing to_patient's winding flip, and a vertex they move (with
  // options.move_vertices) is written to `merged` as the index-space float whose to_patient
  // is the position checked.
  TriangleMesh work;
  work.positions = merged.positions;
  work.triangles = merged.triangles;
  to_patient(work, geometry);
  CollapseOptions in_frame = options;
  in_frame.geometry = &geometry;
  in_frame.frame = &merged.positions;
  const CollapseStats stats = collapse_within_bound(work, reference, in_frame);
  if (geometry.determinant() < 0) {
    for (auto& t : work.triangles) std::swap(t[1], t[2]);
  }
  merged.triangles = std::move(work.triangles);
  remove_unreferenced_vertices(merged);
  return stats;
}

// options.slices_done, said once with every slice when the volume is read no more
// (bounded_reduction.h); never passed to the extractions, which read the volume again.
class ReadsDone {
 public:
  ReadsDone(const Volume& volume, MergeOptions& options)
      : tell_(std::move(options.slices_done)), slices_(volume.size().nz) {
    options.slices_done = nullptr;
  }
  void operator()() {
    if (tell_ && slices_ > 0) tell_(0, slices_);
    tell_ = nullptr;
  }

 private:
  std::function<void(std::int64_t, std::int64_t)> tell_;
  std::int64_t slices_;
};

}  // namespace

CollapseStats collapse_to_count(const Volume& volume, float iso, const ExtractOptions& extract,
                                TriangleMesh& merged, std::size_t target, double bound_mm) {
  return collapse_against(reference_surface(volume, iso, extract), volume.geometry(), merged,
                          {bound_mm, target});
}

ReductionResult extract_type_merged_within(const Volume& volume, float iso,
                                           const ExtractOptions& extract,
                                           const MergeOptions& options, double bound_mm) {
  if (!(bound_mm > 0.0) || !std::isfinite(bound_mm)) {
    throw std::invalid_argument("reduction: the bound must be finite and > 0");
  }
  ReductionResult result;
  MergeOptions at = options;
  ReadsDone reads_done(volume, at);
  at.epsilon_mm = bound_mm;
  result.mesh = extract_type_merged(volume, iso, extract, at, &result.stats);
  result.tries = 1;
  result.bound_mm = bound_mm;
  result.target_met = true;  // no count asked
  if (!result.mesh.triangles.empty()) {
    const TriangleMesh reference = reference_surface(volume, iso, extract);
    reads_done();
    result.collapse = collapse_against(reference, volume.geometry(), result.mesh,
                                       {bound_mm, 0, kLocalErrorShare * bound_mm, true});
  }
  reads_done();
  return result;
}

ReductionResult extract_type_merged_to_count(const Volume& volume, float iso,
                                             const ExtractOptions& extract,
                                             const MergeOptions& options, std::size_t target,
                                             double cap_mm) {
  if (target == 0 || !(cap_mm > 0.0) || !std::isfinite(cap_mm)) {
    throw std::invalid_argument("reduction: the target must be positive and the cap finite and > 0");
  }
  const auto low_enough = static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(target)));
  ReductionResult result;
  MergeOptions without_reads_done = options;
  ReadsDone reads_done(volume, without_reads_done);
  auto run = [&](double bound) {
    MergeOptions at = without_reads_done;
    at.epsilon_mm = bound;
    Try t;
    t.bound = bound;
    t.mesh = extract_type_merged(volume, iso, extract, at, &t.stats);
    ++result.tries;
    return t;
  };
  auto finish = [&](Try&& t) {
    reads_done();
    result.bound_mm = t.bound;
    result.target_met = t.mesh.triangles.size() <= target && t.mesh.triangles.size() >= low_enough;
    result.mesh = std::move(t.mesh);
    result.stats = t.stats;
    return std::move(result);
  };

  Try at_cap = run(cap_mm);
  if (at_cap.mesh.triangles.size() > target) {
    // Merging alone cannot: merge, then bounded collapses, both within half the cap (the
    // larger merge leaves the collapses fewer, better-shaped triangles to work on, so each
    // bound reaches fewer triangles this way than by collapses from a finer merge); if that
    // cannot either, the same within the cap.
    // Marching cubes' surface once for both bounds (extracted after the first merge, so the
    // two are never held at once).
    std::optional<TriangleMesh> reference;
    for (const double bound : {0.5 * cap_mm, cap_mm}) {
      Try start = bound == cap_mm ? std::move(at_cap) : run(bound);
      if (!reference) reference = reference_surface(volume, iso, extract);
      reads_done();  // the cap's merge is made: no try reads the volume after this one
      result.collapse =
          collapse_against(*reference, volume.geometry(), start.mesh, {bound, target});
      if (start.mesh.triangles.size() <= target || bound == cap_mm) return finish(std::move(start));
    }
  }
  // Bisection on log(bound) over the bracket [lo, hi]: hi = few's bound, the smallest known to
  // leave at most target; lo = `many`, the largest known to leave more, or while none is known
  // a floor of 0.01 mm (finer bounds merge nothing more on CT). It starts near where CT merges
  // begin to pay (a tenth of the cap) and stops at a count in the window, or once the bracket
  // is closed to 0.1 %: no bound in between is worth a try.
  std::optional<Try> few = std::move(at_cap);
  double many = 0.0;
  double next = cap_mm / 10.0;
  while (result.tries < kMaxTries) {
    Try t = run(next);
    const std::size_t n = t.mesh.triangles.size();
    if (n > target) {
      many = std::max(many, t.bound);
    } else {
      // Any bound in the window meets the target: the smaller of the two is kept, and it ends.
      const bool in_window = n >= low_enough;
      if (t.bound < few->bound) few = std::move(t);
      if (in_window) break;
    }
    const double lo = many > 0.0 ? many : std::min(cap_mm, 0.01);
    const double hi = few->bound;
    if (hi / lo < 1.0 + 1e-3) break;
    next = std::sqrt(lo * hi);
  }
  return finish(std::move(*few));
}

}  // namespace typemerge::core
