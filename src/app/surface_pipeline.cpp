#include "app/surface_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "core/bounded_reduction.h"
#include "core/inner_wall.h"
#include "core/marching_cubes.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/type_merging.h"
#include "core/window_field.h"
#include "mesh/components.h"
#include "mesh/smoothing.h"
#include "mesh/validity.h"

namespace typemerge::app {
namespace {

using Clock = std::chrono::steady_clock;

// Density of the reported distances' samples (core::area_samples: besides every vertex and
// triangle centroid), as issue 31 states sampled distances.
constexpr double kDistanceSamplesPerMm2 = 1.0;

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

using Details = std::vector<std::pair<std::string, std::string>>;

// What a step says about itself; `check` when the step already checked its result (the
// src/mesh steps do), so it is not computed twice.
struct StepOutput {
  Details details;
  std::optional<core::MeshCheck> check;
};

// Runs one step, then records its time, triangle count and the full validity check (on
// `threads` threads).
template <typename Step>
void run_step(SurfaceResult& result, const std::string& name, unsigned threads, Step&& step) {
  const auto start = Clock::now();
  StepSummary summary;
  summary.step = name;
  StepOutput output = step(result.mesh);
  summary.details = std::move(output.details);
  summary.milliseconds = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  summary.triangles = result.mesh.triangles.size();
  const auto checked = Clock::now();
  summary.check = output.check ? *output.check : core::check_mesh(result.mesh, threads);
  summary.check_milliseconds =
      std::chrono::duration<double, std::milli>(Clock::now() - checked).count();
  result.steps.push_back(std::move(summary));
}

StepOutput component_details(const mesh::ComponentReport& report) {
  return {{{"components_before", std::to_string(report.components_before)},
           {"components_after", std::to_string(report.components_after)},
           {"removed_components", std::to_string(report.removed_components)},
           {"removed_volume_mm3", number(report.removed_volume)}},
          report.validity.check};
}

// Runs a finishing step that moves vertices; with `check` on, counts crossing pairs before
// (once, cached in `crossings`) and after it. When the step added crossings: a step that kept
// the triangles and only moved vertices (smoothing) is repaired by putting the vertices of
// every crossing triangle back where they were, round after round (each round puts back at
// least one more vertex, and with all of them back the surface is the one before the step,
// so it ends); a step that changed the triangles is undone. A smoothed or reduced surface that slicers reject is worse than the
// unsmoothed one.
template <typename Step>
void run_moving_step(SurfaceResult& result, const std::string& name, unsigned threads, bool check,
                     std::optional<std::size_t>& crossings, Step&& step) {
  if (!check) {
    run_step(result, name, threads, std::forward<Step>(step));
    return;
  }
  if (!crossings) crossings = core::find_self_intersections(result.mesh).pairs.size();
  core::TriangleMesh before = result.mesh;
  run_step(result, name, threads, std::forward<Step>(step));
  StepSummary& summary = result.steps.back();
  auto found = core::find_self_intersections(result.mesh);
  const std::size_t made = found.pairs.size();
  summary.details.emplace_back("self_intersecting_pairs", std::to_string(made));
  if (made <= *crossings) {
    crossings = made;
    return;
  }
  std::size_t restored = 0;
  if (result.mesh.triangles == before.triangles) {
    // Normals are one per vertex or none (the extraction makes none, smoothing makes them).
    const bool restore_normals = before.normals.size() == before.positions.size() &&
                                 result.mesh.normals.size() == result.mesh.positions.size();
    std::vector<std::uint8_t> back(result.mesh.positions.size(), 0);
    while (found.pairs.size() > *crossings) {
      std::size_t newly = 0;
      for (const auto& pair : found.pairs) {
        for (std::uint32_t t : pair) {
          for (std::uint32_t v : result.mesh.triangles[t]) {
            if (back[v] != 0) continue;
            back[v] = 1;
            result.mesh.positions[v] = before.positions[v];
            if (restore_normals) result.mesh.normals[v] = before.normals[v];
            ++newly;
          }
        }
      }
      if (newly == 0) break;
      restored += newly;
      found = core::find_self_intersections(result.mesh);
    }
  }
  if (found.pairs.size() <= *crossings && restored > 0) {
    summary.details.emplace_back("vertices_put_back", std::to_string(restored));
    summary.check = core::check_mesh(result.mesh, threads);
    result.warnings.push_back(name + " made " + std::to_string(made - *crossings) +
                              " pair(s) of crossing triangles; " + std::to_string(restored) +
                              " vertices put back where they were");
    crossings = found.pairs.size();
    return;
  }
  result.mesh = std::move(before);
  summary.details.emplace_back("undone", "yes");
  summary.triangles = result.mesh.triangles.size();
  summary.check = core::check_mesh(result.mesh, threads);
  result.warnings.push_back(name + " undone: it made " + std::to_string(made - *crossings) +
                            " pair(s) of crossing triangles");
}

void finish_surface(SurfaceResult& result, const SurfaceSpec& spec, const PipelineOptions& options);
void hollow_surface(SurfaceResult& result, const core::Volume& volume, const SurfaceSpec& spec,
                    const PipelineOptions& options);

}  // namespace

VolumeReaders::VolumeReaders(core::Volume& volume, std::size_t surfaces)
    : volume_(volume), surfaces_(surfaces), said_(static_cast<std::size_t>(volume.size().nz), 0) {}

void VolumeReaders::slices_read(std::int64_t begin, std::int64_t end) {
  const std::lock_guard lock(mutex_);
  const auto nz = static_cast<std::int64_t>(said_.size());
  begin = std::clamp<std::int64_t>(begin, 0, nz);
  end = std::clamp<std::int64_t>(end, begin, nz);
  auto all_said = [&](std::int64_t k) { return said_[static_cast<std::size_t>(k)] == surfaces_; };
  for (std::int64_t k = begin; k < end;) {
    while (k < end && ++said_[static_cast<std::size_t>(k)] != surfaces_) ++k;
    if (k == end) break;
    std::int64_t last = k + 1;  // slices [k, last) all said now
    while (last < end && ++said_[static_cast<std::size_t>(last)] == surfaces_) ++last;
    // With a neighbour freed before, so that the pages a slice shares with it go too.
    volume_.release_slices(k > 0 && all_said(k - 1) ? k - 1 : k,
                           last < nz && all_said(last) ? last + 1 : last);
    k = last + 1;
  }
}

SurfaceResult make_surface(const core::Volume& volume, const SurfaceSpec& spec,
                           const PipelineOptions& options, VolumeReaders* readers) {
  if (readers != nullptr && &readers->volume() != &volume) {
    throw std::logic_error("make_surface: the readers are of another volume");
  }
  // This surface's last read of the volume: every slice not said yet, said (VolumeReaders).
  bool read_all = false;
  const auto reads_done = [&] {
    if (readers != nullptr && !read_all) readers->slices_read(0, volume.size().nz);
    read_all = true;
  };
  // Nothing of this surface reads the volume after its extraction (--hollow does).
  const bool last_read_in_extraction = options.hollow_mm == 0;
  SurfaceResult result;
  core::TriangleMesh marching_cubes;  // for measure_distance, with tm
  core::ExtractOptions extract;
  extract.close_borders = options.close_borders;
  extract.threads = options.threads;
  extract.mode = options.algorithm == "classic" ? core::ExtractOptions::Mode::classic
                                                : core::ExtractOptions::Mode::consistent;
  // No gradient normals: nothing a conversion writes stores vertex normals (STL, 3MF and the
  // preview use facet normals, PLY and OBJ none), and smoothing recomputes them.
  extract.vertex_normals = false;

  run_step(result, "extract (" + options.algorithm + ")", options.threads, [&](core::TriangleMesh& mesh) {
    // A window becomes the field min(v − lo, hi − v) at iso 0 (core/window_field.h).
    const bool window = spec.hi.has_value();
    core::Volume field;
    if (window) {
      field = core::window_field(volume, static_cast<float>(spec.lo),
                                 static_cast<float>(*spec.hi));
      if (last_read_in_extraction) reads_done();  // the extraction reads the field
    }
    const core::Volume& source = window ? field : volume;
    const float iso = window ? 0.0f : static_cast<float>(spec.lo);
    Details details;
    const FinishOptions& finish = options.finish;
    // Whether the extractor's own last read of the volume is this surface's: not for a window
    // (it reads the field), --hollow, or type merging's distance measurement (marching cubes
    // of the volume after it). Then the extractor says when: type merging slice by slice, a
    // reduction before its collapses, marching cubes before joining its slabs.
    const bool extractor_says = !window && last_read_in_extraction &&
                                !(options.measure_distance && options.algorithm == "tm");
    const auto say_all = [&](std::int64_t, std::int64_t) { reads_done(); };
    core::MergeOptions reduction;
    if (extractor_says) reduction.slices_done = say_all;
    if (options.algorithm == "tm") {
      core::MergeStats stats;
      if (finish.reduce_to_triangles > 0) {
        const core::IndexToPatient& g = volume.geometry();
        const double cap =
            finish.max_error_mm > 0
                ? finish.max_error_mm
                : core::kReductionCapSteps * std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
        core::ReductionResult reduced = core::extract_type_merged_to_count(
            source, iso, extract, reduction, finish.reduce_to_triangles, cap);
        mesh = std::move(reduced.mesh);
        stats = reduced.stats;
        result.reduction = ReductionSummary{finish.reduce_to_triangles, mesh.triangles.size(),
                                            reduced.bound_mm, cap, reduced.target_met,
                                            reduced.tries, reduced.collapse.collapses};
        if (!reduced.target_met) {
          result.warnings.push_back(
              "--reduce-to " + std::to_string(finish.reduce_to_triangles) + " not met: " +
              std::to_string(mesh.triangles.size()) + " triangles within " +
              number(reduced.bound_mm) + " mm (the bound's cap is " + number(cap) + " mm)");
        }
      } else if (finish.max_error_mm > 0 && !finish.merge_only) {
        core::ReductionResult reduced = core::extract_type_merged_within(
            source, iso, extract, reduction, finish.max_error_mm);
        mesh = std::move(reduced.mesh);
        stats = reduced.stats;
        result.reduction = ReductionSummary{0, mesh.triangles.size(), finish.max_error_mm,
                                            finish.max_error_mm, true, reduced.tries,
                                            reduced.collapse.collapses};
      } else {
        core::MergeOptions merge;
        merge.epsilon_mm = finish.max_error_mm;  // 0: the default, half a voxel
        if (readers != nullptr && extractor_says) {
          merge.slices_done = [readers](std::int64_t begin, std::int64_t end) {
            readers->slices_read(begin, end);
          };
          merge.return_idle_pages = true;
          read_all = true;  // the extraction says every slice
        }
        mesh = core::extract_type_merged(source, iso, extract, merge, &stats);
        if (finish.max_error_mm > 0) {
          result.reduction = ReductionSummary{0, mesh.triangles.size(), finish.max_error_mm,
                                              finish.max_error_mm, true, 1, 0};
        }
      }
      std::size_t disks = 0;
      for (std::size_t n : stats.blocks_merged) disks += n;
      details = {{"mc_triangles", std::to_string(stats.triangles_before)},
                 {"merged_disks", std::to_string(disks)},
                 {"face_vertices_thinned",
                  std::to_string(stats.face_vertices_removed - stats.face_vertices_restored)}};
      if (result.reduction) {
        details.emplace_back("bound_mm", number(result.reduction->bound_mm));
        details.emplace_back("extractions", std::to_string(result.reduction->extractions));
        details.emplace_back("collapses", std::to_string(result.reduction->collapses));
      }
    } else {
      core::ExtractOptions freeing = extract;
      if (extractor_says) freeing.slices_done = say_all;
      mesh = core::extract_isosurface(source, iso, freeing);
    }
    core::to_patient(mesh, volume.geometry());
    if (options.measure_distance) {
      if (options.algorithm == "tm") {
        marching_cubes = core::extract_isosurface(source, iso, extract);
        core::to_patient(marching_cubes, volume.geometry());
        const auto d = core::area_sampled_distance(marching_cubes, mesh, kDistanceSamplesPerMm2,
                                                   options.threads);
        result.distance = DistanceSummary{d.hausdorff(), d.mean(), std::nullopt, std::nullopt};
      } else {
        result.distance = DistanceSummary{};  // it is marching cubes' surface
      }
    }
    if (last_read_in_extraction) reads_done();
    return StepOutput{details, std::nullopt};
  });

  if (options.finish.enabled && !result.mesh.empty()) {
    finish_surface(result, spec, options);
    if (result.distance && !marching_cubes.empty() && result.steps.size() > 1) {
      // The finished surface's samples against marching cubes' surface.
      const core::TriangleMesh samples = core::area_samples(result.mesh, kDistanceSamplesPerMm2);
      const auto d = core::vertex_to_mesh_distance(samples, marching_cubes, options.threads);
      result.distance->finished_max_mm = d.max;
      result.distance->finished_mean_mm = d.mean;
    }
  }
  marching_cubes = {};
  if (options.hollow_mm > 0 && !result.mesh.empty()) hollow_surface(result, volume, spec, options);
  reads_done();
  const bool finished = (options.finish.enabled || options.hollow_mm > 0) && !result.mesh.empty();
  if (finished && !result.steps.back().check.closed_manifold()) {
    const auto problems = mesh::check_validity(result.mesh).problems();
    for (const auto& p : problems) result.warnings.push_back("final mesh: " + p);
  }
  return result;
}

namespace {

void finish_surface(SurfaceResult& result, const SurfaceSpec& spec, const PipelineOptions& options) {
  const FinishOptions& finish = options.finish;

  const double min_volume = finish.min_component_mm3.value_or(spec.min_component_mm3);
  const bool keep_largest = finish.keep_largest || spec.keep_largest;
  const bool fill = finish.fill_cavities.value_or(spec.fill_cavities);
  if (keep_largest) {
    // Filled at once when asked: one shell, without searching which cavities are its own.
    const auto cavities = fill ? mesh::Cavities::fill : mesh::Cavities::keep;
    run_step(result, fill ? "keep largest solid, cavities filled" : "keep largest solid",
             options.threads,
             [&result, &options, cavities](core::TriangleMesh& mesh) {
               return component_details(mesh::keep_largest_component(
                   mesh, cavities, &result.steps.back().check, options.threads));
             });
  }
  if (min_volume > 0) {
    run_step(result, "remove components under " + number(min_volume) + " mm3", options.threads,
             [&](core::TriangleMesh& mesh) {
               return component_details(mesh::remove_small_components(
                   mesh, min_volume, &result.steps.back().check, options.threads));
             });
  }
  if (fill && !keep_largest) {
    run_step(result, "fill cavities", options.threads, [&result, &options](core::TriangleMesh& mesh) {
      return component_details(
          mesh::fill_cavities(mesh, &result.steps.back().check, options.threads));
    });
  }
  std::optional<std::size_t> crossings;  // of the surface as it stands, once counted
  if (finish.smooth_iterations > 0) {
    run_moving_step(result, "Taubin smoothing", options.threads, options.check_intersections, crossings,
                    [&](core::TriangleMesh& mesh) {
      mesh::SmoothingOptions smoothing;
      smoothing.iterations = finish.smooth_iterations;
      const auto report = mesh::smooth_mesh(mesh, smoothing);
      return StepOutput{{{"iterations", std::to_string(report.iterations)},
                         {"relative_volume_change", number(report.relative_volume_change)}},
                        report.validity.check};
    });
  }
}

// The inner wall at options.hollow_mm inside the finished surface, appended as a cavity.
void hollow_surface(SurfaceResult& result, const core::Volume& volume, const SurfaceSpec& spec,
                    const PipelineOptions& options) {
  run_step(result, "hollow " + number(options.hollow_mm) + " mm", options.threads, [&](core::TriangleMesh& mesh) {
    const bool window = spec.hi.has_value();
    core::Volume field;
    if (window) {
      field = core::window_field(volume, static_cast<float>(spec.lo), static_cast<float>(*spec.hi));
    }
    const core::Volume& source = window ? field : volume;
    const float iso = window ? 0.0f : static_cast<float>(spec.lo);
    core::InnerWallOptions wall;
    wall.wall_mm = options.hollow_mm;
    wall.threads = options.threads;
    wall.fill_enclosed = options.finish.enabled &&
                         options.finish.fill_cavities.value_or(spec.fill_cavities);
    // How far the finished surface may be from the voxels' marching cubes: type merging's
    // bound (its default half voxel, or the reduction's bound in mm) and a light smoothing
    // within one voxel.
    const auto& g = volume.geometry();
    wall.outer_deviation_mm = std::max({g.spacing(0), g.spacing(1), g.spacing(2)}) +
                              (result.reduction ? result.reduction->bound_mm : 0.0);
    const double outer_volume = result.steps.back().check.volume;
    core::InnerWallStats stats;
    const core::TriangleMesh inner = core::extract_inner_wall(source, iso, mesh, wall, &stats);
    field = {};
    const auto offset = static_cast<std::uint32_t>(mesh.positions.size());
    mesh.positions.insert(mesh.positions.end(), inner.positions.begin(), inner.positions.end());
    // The wall has normals exactly when `mesh` has (extract_inner_wall), so they stay one per
    // vertex or none.
    mesh.normals.insert(mesh.normals.end(), inner.normals.begin(), inner.normals.end());
    for (const auto& t : inner.triangles) {
      mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    }
    HollowSummary summary{options.hollow_mm, outer_volume, stats.hollow_volume_mm3,
                          stats.components - stats.dropped_outside - stats.dropped_small,
                          stats.dropped_outside, stats.dropped_small};
    result.hollow = summary;
    if (inner.empty()) {
      result.warnings.push_back("hollow: no inner wall, the solid is nowhere thicker than " +
                                number(2 * options.hollow_mm) + " mm");
    }
    return StepOutput{{{"wall_mm", number(options.hollow_mm)},
                       {"band_samples", std::to_string(stats.band_samples)},
                       {"inner_components", std::to_string(summary.inner_components)},
                       {"dropped_outside", std::to_string(stats.dropped_outside)},
                       {"dropped_small", std::to_string(stats.dropped_small)},
                       {"hollow_volume_mm3", number(stats.hollow_volume_mm3)}},
                      std::nullopt};
  });
}

}  // namespace

}  // namespace typemerge::app
