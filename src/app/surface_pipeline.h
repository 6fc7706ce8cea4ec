// The surface part of `convert`: extraction → patient space → finishing, each step timed and
// validated, for one tissue. Composes core (extraction, type merging) and mesh (OpenMesh
// finishing); knows nothing of files or the command line.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/mesh.h"
#include "core/mesh_checks.h"
#include "core/volume.h"

namespace typemerge::app {

// What to extract: value >= lo, or lo <= value <= hi.
struct SurfaceSpec {
  std::string name;  // file stem: the preset name, "iso" or "window"
  std::string label; // for messages: "preset bone", "iso 300 HU"
  double lo = 0;
  std::optional<double> hi;
  bool from_preset = false;
  double min_component_mm3 = 0;  // preset default for finishing
  bool fill_cavities = false;    // preset default for finishing
  bool keep_largest = false;     // preset default for finishing
  std::array<std::uint8_t, 3> srgb{};  // display colour of its object in a 3MF package
  // `--iso auto`: lo is Otsu's threshold of the volume, set once it is preprocessed.
  bool auto_iso = false;
};

struct FinishOptions {
  bool enabled = true;                       // --finish none turns every step off
  std::optional<double> min_component_mm3;   // overrides the preset's
  bool keep_largest = false;
  std::optional<bool> fill_cavities;         // overrides the preset's
  int smooth_iterations = 0;                 // Taubin; 0 = off
  // --reduce-to / --max-error: type merging's own reduction, applied at extraction (so with
  // enabled false too), algorithm tm only (core/bounded_reduction.h). reduce_to_triangles: the
  // smallest bound in mm up to the cap (max_error_mm if given, else kReductionCapSteps × the
  // finest voxel step) giving 0.99 N to N triangles; max_error_mm alone: the merge within that
  // bound, then bounded collapses within it (core::extract_type_merged_within), or the merge
  // alone with merge_only. 0 = not given.
  std::size_t reduce_to_triangles = 0;
  double max_error_mm = 0.0;
  bool merge_only = false;  // --merge-only: max_error_mm alone without the collapses
};

struct PipelineOptions {
  std::string algorithm = "tm";  // tm | mc | classic
  bool close_borders = true;
  unsigned threads = 0;  // extraction threads; 0 = all cores (the output does not depend on it)
  FinishOptions finish;
  // Count crossing triangle pairs (core/self_intersections.h) after every finishing step that
  // moves vertices (smoothing) and undo a step that adds any.
  bool check_intersections = false;
  // Measure each surface's two-sided distance to marching cubes' surface on the same grid
  // (sampled over both surfaces, ≥ 1 point per mm²), for --report: SurfaceResult::distance.
  bool measure_distance = false;
  // --hollow MM: after the finishing steps, the inner wall at MM inside the surface is added
  // as a cavity (core/inner_wall.h); 0 = solid.
  double hollow_mm = 0;
};

struct StepSummary {
  std::string step;
  double milliseconds = 0;        // the step itself
  double check_milliseconds = 0;  // checking its result (0 when the step derived the check)
  std::size_t triangles = 0;  // after the step
  core::MeshCheck check;      // after the step
  std::vector<std::pair<std::string, std::string>> details;
};

// What --hollow did (volumes in mm³).
struct HollowSummary {
  double wall_mm = 0;
  double outer_volume = 0;   // enclosed by the outer surface (the solid model's volume)
  double hollow_volume = 0;  // enclosed by the inner wall: the material saved
  std::size_t inner_components = 0;
  std::size_t dropped_outside = 0;
  std::size_t dropped_small = 0;
};

// What --reduce-to / --max-error did.
struct ReductionSummary {
  std::size_t target_triangles = 0;  // 0: a bound alone
  std::size_t triangles = 0;         // what the extraction made
  double bound_mm = 0.0;             // the bound it was made within
  double cap_mm = 0.0;               // the largest bound the count could use
  bool target_met = true;            // 0.99 N <= triangles <= N (true for a bound alone)
  std::size_t extractions = 1;
  std::size_t collapses = 0;         // of the second stage (core/bounded_collapse.h)
};

// Sampled distances (mm) to marching cubes' surface on the same grid.
struct DistanceSummary {
  double max_mm = 0.0;   // two-sided, of the extracted surface
  double mean_mm = 0.0;  // mean over the samples of both surfaces
  // From the finished surface (after smoothing and component removal) to marching cubes'
  // surface, one-sided (removed components would count the other way); when it was finished.
  std::optional<double> finished_max_mm;
  std::optional<double> finished_mean_mm;
};

struct SurfaceResult {
  core::TriangleMesh mesh;  // LPS mm
  std::optional<HollowSummary> hollow;
  std::optional<ReductionSummary> reduction;
  std::optional<DistanceSummary> distance;
  std::vector<StepSummary> steps;
  std::vector<std::string> warnings;
};

// The surfaces made from one volume, when the caller reads its samples no more once they are
// made: each surface says which slices it has read for the last time, and a slice that every
// surface has said is returned to the operating system (Volume::release_slices: its samples
// read as zeros afterwards, the geometry stays). So the volume shrinks while the surfaces are
// extracted, and finishing, writing and a reduction's collapses do not hold it. Thread-safe:
// the surfaces may be made at once, each on several threads.
class VolumeReaders {
 public:
  VolumeReaders(core::Volume& volume, std::size_t surfaces);
  core::Volume& volume() const { return volume_; }
  // Slices [begin, end) one surface reads no more. A surface says each slice at most once.
  void slices_read(std::int64_t begin, std::int64_t end);

 private:
  core::Volume& volume_;
  const std::size_t surfaces_;
  std::mutex mutex_;
  std::vector<std::size_t> said_;  // per slice, by how many surfaces
};

// `readers`: the readers of this same volume, this surface among them (null: the volume is
// kept). Type merging without a reduction, a window, --hollow or the distance measurement says
// its slices as it passes them (core::MergeOptions::slices_done; its idle scratch then gives
// its pages back too, MergeOptions::return_idle_pages); any other surface says them all after
// its last read: after extraction (for a window, once its field is made), before a
// reduction's collapses (core/bounded_reduction.h), or after --hollow, which reads the volume
// again. The surface is the same either way.
SurfaceResult make_surface(const core::Volume& volume, const SurfaceSpec& spec,
                           const PipelineOptions& options, VolumeReaders* readers = nullptr);

}  // namespace typemerge::app
