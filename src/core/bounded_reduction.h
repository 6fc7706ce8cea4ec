// Type merging to a triangle count: the smallest bound in millimetres (up to a cap) whose
// surface has at most `target` triangles and at least 99 % of it.
//
// Every result keeps all type merging's guarantees: closed, manifold, oriented, marching
// cubes' Euler characteristic and components, no crossings, no more caps or needles than
// marching cubes, and within its bound of marching cubes' surface, two-sided over both whole
// surfaces.
//
// The search: the merge at the cap first. If it leaves few enough triangles, bisection on
// log(bound) between a bound known to leave too many and one known to leave few enough, each
// try one extract_type_merged at MergeOptions::epsilon_mm, until the count falls in
// [0.99 target, target] or 24 tries are spent; the surface returned is the one with the
// smallest bound that left at most `target` (target_met false if its count is below 0.99
// target). The count is not strictly monotone in the bound (a larger disk can replace smaller
// ones and need a fallback), so the bracket is kept by the tries' counts, not assumed.
//
// If even the cap's merge leaves more than `target`, merging alone cannot reach it: the second
// stage, bounded collapses (bounded_collapse.h; without placement, which at a count lowers the mean
// distance by about a tenth for about a quarter more time, so that the count stays faster than
// quadric decimation: docs/benchmarks.md) of the merged surface against marching cubes' own, within
// the same bound, run until the target: first at half the cap (the merge and the collapses both
// within it), then, if that stops short, at the cap. A larger merge leaves the collapses fewer,
// better-shaped triangles, so each bound reaches fewer triangles this way than by collapses from a
// finer merge (docs/benchmarks.md). Where even the cap stops short, the surface is as far as the
// cap allowed, with target_met false.
#pragma once

#include <cstddef>

#include "core/bounded_collapse.h"
#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/type_merging.h"
#include "core/volume.h"

namespace typemerge::core {

// The cap's default: this many times the grid's finest step (IndexToPatient::spacing).
inline constexpr double kReductionCapSteps = 5.0;

// Within a bound alone (extract_type_merged_within), the collapses' local limit
// (CollapseOptions::local_rms) as a share of the bound.
inline constexpr double kLocalErrorShare = 0.1;

struct ReductionResult {
  TriangleMesh mesh;        // index space, as extract_type_merged
  MergeStats stats;
  double bound_mm = 0.0;    // the bound of the surface returned
  bool target_met = false;  // 0.99 target <= triangles <= target
  std::size_t tries = 0;    // extractions made
  CollapseStats collapse;   // the second stage's, when it ran
};

// The second stage: bounded collapses (bounded_collapse.h) of `merged` (index space, as
// extract_type_merged makes it, within bound_mm of marching cubes' surface) down to `target`
// triangles or as far as bound_mm allows, judged against marching cubes' surface of the same
// volume, iso and options, in patient millimetres.
CollapseStats collapse_to_count(const Volume& volume, float iso, const ExtractOptions& extract,
                                TriangleMesh& merged, std::size_t target, double bound_mm);

// Type merging within bound_mm, then bounded collapses of its surface within the same bound (the
// second stage above, without a count, with placement: the kept vertex moves to its quadric's
// point, CollapseOptions::move_vertices) as long as each one's local quadric estimate stays within
// kLocalErrorShare × bound_mm (CollapseOptions::local_rms): the fewer triangles the bound allows at
// a mean distance near the merge's. Collapsing on until the bound alone stops it takes many times
// longer and leaves several times the mean distance (docs/benchmarks.md). Every guarantee of the
// header above holds; target_met is true. `options` gives everything but epsilon_mm. Throws
// std::invalid_argument for a bound not finite and > 0.
ReductionResult extract_type_merged_within(const Volume& volume, float iso,
                                           const ExtractOptions& extract,
                                           const MergeOptions& options, double bound_mm);

// `options` gives everything but epsilon_mm (its epsilon_voxels is ignored). cap_mm > 0.
// For both functions, options.slices_done (when set) is called once, with every slice
// [0, nz), as soon as the volume is read no more: before the collapses, which take most of
// a reduction's time and memory, or else before returning. The extractions never call it (each
// try reads the whole volume), so a holder that releases the slices it names
// (Volume::release_slices) gets the same surface with the volume's memory freed for the
// collapses.
// Throws std::invalid_argument for target 0 or cap_mm not finite and positive.
ReductionResult extract_type_merged_to_count(const Volume& volume, float iso,
                                             const ExtractOptions& extract,
                                             const MergeOptions& options, std::size_t target,
                                             double cap_mm);

}  // namespace typemerge::core
