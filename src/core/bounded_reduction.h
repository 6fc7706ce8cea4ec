// Type merging to a triangle count: the smallest bound in millimetres (up to a cap) whose
// merge has at most `target` triangles and at least 99 % of it.
//
// Every try is one extract_type_merged at a bound in mm (MergeOptions::epsilon_mm), so every
// result keeps all its guarantees: closed, manifold, oriented, marching cubes' Euler
// characteristic and components, no crossings, no more caps or needles than marching cubes,
// and within its bound of marching cubes' surface, two-sided over both whole surfaces.
//
// The search: the cap first (if even it leaves more than `target` triangles, the target is
// out of reach by merging and the cap's surface is returned with target_met false); then
// bisection on log(bound) between a bound known to leave too many triangles and one known to
// leave few enough, until the count falls in [0.99 target, target] or 24 tries are spent; the
// surface returned is then the one with the smallest bound that left at most `target`
// (target_met false if its count is below 0.99 target). The count is not strictly monotone in
// the bound (a larger disk can replace smaller ones and need a fallback), so the bracket is
// kept by the tries' counts, not assumed.
#pragma once

#include <cstddef>

#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/type_merging.h"
#include "core/volume.h"

namespace typemerge::core {

// The cap's default: this many times the grid's finest step (IndexToPatient::spacing).
inline constexpr double kReductionCapSteps = 5.0;

struct ReductionResult {
  TriangleMesh mesh;        // index space, as extract_type_merged
  MergeStats stats;
  double bound_mm = 0.0;    // the bound of the surface returned
  bool target_met = false;  // 0.99 target <= triangles <= target
  std::size_t tries = 0;    // extractions made
};

// `options` gives everything but epsilon_mm (its epsilon_voxels is ignored). cap_mm > 0.
// Throws std::invalid_argument for target 0 or cap_mm not finite and positive.
ReductionResult extract_type_merged_to_count(const Volume& volume, float iso,
                                             const ExtractOptions& extract,
                                             const MergeOptions& options, std::size_t target,
                                             double cap_mm);

}  // namespace typemerge::core
