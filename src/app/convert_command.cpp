#include "app/convert_command.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <future>
#include <optional>
#include <system_error>
#include <limits>
#include <ostream>

#include "app/exit_codes.h"
#include "app/label_mode.h"
#include "app/memory_budget.h"
#include "app/presets.h"
#include "app/version.h"
#include "core/self_intersections.h"
#include "core/window_field.h"
#include "dicom/series_loader.h"
#include "io/atomic_file.h"
#include "io/preview_png.h"
#include "io/mesh_writers.h"
#include "io/three_mf_writer.h"
#include "preprocess/body_mask.h"
#include "preprocess/crop.h"
#include "preprocess/denoise.h"
#include "preprocess/otsu_threshold.h"
#include "preprocess/resample.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::ordered_json;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A preset assumes Hounsfield units and a tissue that is there: check both rather than write
// an empty mesh or a box (everything inside).
void check_tissue(const core::Volume& volume, float min_hu, float max_hu, const SurfaceSpec& spec) {
  if (spec.from_preset && !dicom::hounsfield_plausibility_warning(min_hu, max_hu).empty()) {
    char text[96];
    std::snprintf(text, sizeof text, "%.0f to %.0f", double(min_hu), double(max_hu));
    throw CommandError{kExitInputRefused,
                       std::string("the values of this series do not look like Hounsfield units (") +
                           text + "), so " + spec.label +
                           " would not fit; give --iso or --window in this data's units"};
  }
  const float hi = spec.hi ? static_cast<float>(*spec.hi) : std::numeric_limits<float>::infinity();
  const auto cover = core::window_cover(volume, static_cast<float>(spec.lo), hi);
  if (cover == core::WindowCover::none) {
    throw CommandError{kExitInputRefused, "no surface: no voxel inside " + spec.label +
                                              ", the tissue is absent from this series"};
  }
  if (cover == core::WindowCover::all) {
    throw CommandError{kExitInputRefused, "every voxel is inside " + spec.label +
                                              ": the surface would be the volume's box"};
  }
}

// --reduce-to and --max-error are type merging's own; refused where they cannot mean that.
void check_reduction_options(const ConvertOptions& options) {
  if (!options.removed_decimator.empty()) {
    throw CommandError{kExitUsage,
                       "--decimator was removed: --reduce-to and --max-error are type merging "
                       "itself now, with every guarantee kept (closed, no crossings, within the "
                       "bound); drop --decimator"};
  }
  const bool reduces = options.finish_options.reduce_to_triangles > 0 ||
                       options.finish_options.max_error_mm > 0;
  if (reduces && options.algorithm != "tm") {
    throw CommandError{kExitUsage, "--reduce-to and --max-error are type merging's reduction; "
                                   "--algorithm " + options.algorithm +
                                   " is the unreduced surface: drop one of them"};
  }
}

ordered_json reduction_json(const SurfaceResult& result) {
  if (!result.reduction) return nullptr;
  const ReductionSummary& r = *result.reduction;
  return {{"target_triangles", r.target_triangles > 0 ? ordered_json(r.target_triangles)
                                                      : ordered_json(nullptr)},
          {"triangles", r.triangles},
          {"bound_mm", r.bound_mm},
          {"cap_mm", r.cap_mm},
          {"target_met", r.target_met},
          {"extractions", r.extractions},
          {"collapses", r.collapses}};
}

ordered_json distance_json(const SurfaceResult& result) {
  if (!result.distance) return nullptr;
  const DistanceSummary& d = *result.distance;
  auto optional = [](const std::optional<double>& v) {
    return v ? ordered_json(*v) : ordered_json(nullptr);
  };
  return {{"max_mm", d.max_mm},
          {"mean_mm", d.mean_mm},
          {"finished_max_mm", optional(d.finished_max_mm)},
          {"finished_mean_mm", optional(d.finished_mean_mm)}};
}

ordered_json check_json(const core::MeshCheck& check) {
  return {{"closed_manifold", check.closed_manifold()},
          {"boundary_edges", check.boundary_edges},
          {"non_manifold_edges", check.non_manifold_edges},
          {"non_manifold_vertices", check.non_manifold_vertices},
          {"inconsistent_edges", check.inconsistent_edges},
          {"degenerate_triangles", check.degenerate_triangles},
          {"components", check.components},
          {"euler_characteristic", check.euler_characteristic}};
}

ordered_json record_json(const preprocess::StepRecord& record, double ms) {
  ordered_json parameters = ordered_json::object();
  for (const auto& [key, value] : record.parameters) parameters[key] = value;
  return {{"step", record.step}, {"description", record.description},
          {"parameters", parameters}, {"warnings", record.warnings}, {"ms", ms}};
}

// Where the surfaces go: one 3MF package holding them all when OUT ends in .3mf; else OUT
// itself for one surface and OUT/<name>.stl for several.
bool writes_package(const ConvertOptions& options) {
  const std::string extension = fs::path(options.output).extension().string();
  return extension == ".3mf" || extension == ".3MF";
}

fs::path output_path(const ConvertOptions& options, const SurfaceSpec& spec, std::size_t count) {
  if (writes_package(options)) return options.output;
  if (count == 1 && fs::path(options.output).has_extension()) return options.output;
  return fs::path(options.output) / (spec.name + ".stl");
}

// The PNG beside an output; in a package of several surfaces, named after both.
fs::path preview_path(const ConvertOptions& options, const SurfaceSpec& spec, std::size_t count) {
  fs::path png = output_path(options, spec, count);
  if (writes_package(options) && count > 1) {
    return png.replace_extension("." + spec.name + ".png");
  }
  return png.replace_extension(".png");
}

// The output frame: LPS as extracted, or RAS (x and y negated: a rotation, so windings stay
// outward).
void to_output_space(core::TriangleMesh& mesh, const ConvertOptions& options) {
  if (options.space != "ras") return;
  for (auto& p : mesh.positions) {
    p[0] = -p[0];
    p[1] = -p[1];
  }
  for (auto& n : mesh.normals) {
    n[0] = -n[0];
    n[1] = -n[1];
  }
}

// --center: every surface moves by the one offset that centres their joint bounding box on the
// origin, so that surfaces of one run stay in one frame (bone inside skin, as printed together).
void center_together(std::vector<SurfaceResult>& results) {
  core::BoundingBox joint;
  for (const SurfaceResult& result : results) {
    const core::BoundingBox box = core::bounding_box(result.mesh);
    for (int c = 0; c < 3; ++c) {
      joint.min[c] = std::min(joint.min[c], box.min[c]);
      joint.max[c] = std::max(joint.max[c], box.max[c]);
    }
  }
  if (joint.min[0] > joint.max[0]) return;  // no vertex at all
  // The bounds are float positions held in double, so the casts back are exact.
  std::array<float, 3> offset{};
  for (int c = 0; c < 3; ++c) offset[c] = 0.5f * (float(joint.min[c]) + float(joint.max[c]));
  for (SurfaceResult& result : results) {
    for (auto& p : result.mesh.positions) {
      for (int c = 0; c < 3; ++c) p[c] -= offset[c];
    }
  }
}

// Why the volume's values are not Hounsfield units (a modality other than CT, or values without
// air near -1000), or empty when they are.
std::string not_hounsfield_reason(const dicom::SeriesInfo& series, const dicom::LoadedSeries& loaded) {
  if (!series.modality.empty() && series.modality != "CT") {
    return "the series is " + series.modality + ", not CT";
  }
  if (!dicom::hounsfield_plausibility_warning(loaded.min_hu, loaded.max_hu).empty()) {
    return "its values (" + preprocess::detail::format_number(loaded.min_hu) + " to " +
           preprocess::detail::format_number(loaded.max_hu) + ") have no air near -1000 HU";
  }
  return {};
}

}  // namespace

std::vector<SurfaceSpec> surface_specs(const ConvertOptions& options) {
  std::vector<SurfaceSpec> specs;
  for (const std::string& name : options.presets) {
    const auto preset = find_preset(name);
    if (!preset) {
      throw CommandError{kExitUsage, "unknown preset '" + name + "' (see `typemerge presets`)"};
    }
    SurfaceSpec spec{preset->name, "preset " + preset->name, preset->lo, std::nullopt, true,
                     preset->min_component_mm3, preset->fill_cavities, preset->keep_largest,
                     preset->srgb};
    if (std::isfinite(preset->hi)) spec.hi = preset->hi;
    specs.push_back(spec);
  }
  if (options.iso == "auto") {
    // The value and the label are filled in once the volume is known (auto_iso_spec).
    SurfaceSpec spec{"iso", "iso auto", 0, std::nullopt, false, 0, false, false};
    spec.auto_iso = true;
    specs.push_back(spec);
  } else if (!options.iso.empty()) {
    // from_chars: the C locale's '.', whatever the environment's locale.
    double iso = 0;
    const char* end = options.iso.data() + options.iso.size();
    const auto parsed = std::from_chars(options.iso.data(), end, iso);
    if (parsed.ec != std::errc() || parsed.ptr != end || !std::isfinite(iso)) {
      throw CommandError{kExitUsage, "--iso wants a number or 'auto', not '" + options.iso + "'"};
    }
    char label[64];
    std::snprintf(label, sizeof label, "iso %g HU", iso);
    specs.push_back({"iso", label, iso, std::nullopt, false, 0, false, false,
                     io::kSurfaceGrey});
  }
  if (options.window.size() == 2) {
    if (!(options.window[0] <= options.window[1])) {
      throw CommandError{kExitUsage, "--window LO,HI needs LO <= HI"};
    }
    specs.push_back({"window", "window", options.window[0], options.window[1], false, 0, false,
                     false, io::kSurfaceGrey});
  }
  if (specs.empty()) {
    throw CommandError{kExitUsage,
                       "say what to extract: --preset NAME, --iso HU|auto or --window LO,HI, "
                       "or --labels all for a label map"};
  }
  return specs;
}

void add_convert_command(CLI::App& app, ConvertOptions& options) {
  CLI::App* command = app.add_subcommand(
      "convert", "Extract tissue surfaces as binary STL in patient LPS mm");
  add_input_options(*command, options.input);
  command->add_option("--series", options.series_id, "Series id from `typemerge info`");
  command->add_option("-o,--output", options.output,
                      "Output file (one surface: .stl, .ply, .obj), .3mf package (one object "
                      "per surface, all in one) or folder (several surfaces as STL)")
      ->required();
  command->add_option("--threads", options.threads,
                      "Extraction threads (default 0: all cores); outputs are identical for any "
                      "value")
      ->check(CLI::Range(0u, 256u));
  command->add_option("--report", options.report, "Write a JSON report of the run");
  // For batch, whose summary does not use them (hidden: not a user's option).
  command
      ->add_flag_callback(
          "--report-without-distances", [&options] { options.report_distances = false; },
          "Leave the sampled distances to marching cubes' surface out of the report")
      ->group("");
  command->add_option("--max-memory", options.max_memory,
                      "Memory bound, e.g. 8G (default: 3/4 of the physical memory): a series "
                      "whose conversion would need more (about 4 bytes a voxel, 6 when its values "
                      "need floats, + 211 MiB for one surface, "
                      "more per surface, window, --reduce-to and --hollow) is refused "
                      "before loading, and the process's address space is limited to it");
  CLI::App* surface = command->add_option_group("Surface");
  add_surface_options(*surface, options);
  add_label_options(*command, *surface, options);
}

void add_surface_options(CLI::App& command_group, ConvertOptions& options) {
  CLI::App* command = &command_group;
  auto* preset = command->add_option("--preset", options.presets,
                                     "Tissue preset(s), comma-separated (see `typemerge presets`)")
                     ->delimiter(',');
  auto* iso = command->add_option("--iso", options.iso,
                                  "Iso value in HU (inside: value >= iso), or auto: Otsu's "
                                  "threshold of the volume (air against tissue: a skin-like "
                                  "surface; for any modality)");
  auto* window = command->add_option("--window", options.window,
                                     "HU window LO,HI: the surface around voxels inside it")
                     ->delimiter(',')
                     ->expected(2);
  preset->excludes(iso)->excludes(window);
  iso->excludes(window);
  auto* hollow = command->add_option(
      "--hollow", options.hollow_mm,
      "Hollow each surface to a shell of this wall thickness in mm (an inner wall added as a "
      "cavity after finishing; the report states the material saved)");
  hollow->check(CLI::PositiveNumber);
  command->add_option("--algorithm", options.algorithm,
                      "tm: type merging (default); mc: consistent marching cubes; classic: "
                      "fixed-table marching cubes (shows the holes of ambiguous cubes)")
      ->check(CLI::IsMember({"tm", "mc", "classic"}));
  command->add_flag("--open-borders", options.open_borders,
                    "Leave surfaces open where they meet the volume border (default: closed)")
      ->excludes(hollow);
  command->add_flag("--check-intersections", options.check_intersections,
                    "Count crossing triangle pairs (exact) in each output and in the report; "
                    "a smoothing step that adds crossings is undone");
  command->add_option("--finish", options.finish,
                      "default: the preset's clean-up; none: the extractor's surface unchanged")
      ->check(CLI::IsMember({"default", "none"}));
  command->add_option("--min-component", options.min_component_mm3,
                      "Remove components enclosing less than this many mm3");
  command->add_flag("--keep-largest", options.finish_options.keep_largest,
                    "Keep only the largest solid (its cavities stay unless --fill-cavities)");
  command->add_flag("--fill-cavities", options.fill_cavities,
                    "Fill cavities: remove every shell inside another (one shell per solid)");
  command->add_option("--smooth", options.finish_options.smooth_iterations,
                      "Taubin smoothing iterations (volume-preserving; default 0)")
      ->check(CLI::Range(0, 1000));
  CLI::Option* reduce_to =
      command->add_option("--reduce-to", options.finish_options.reduce_to_triangles,
                          "Type merging to at most this many triangles (and at least 99 % of it) "
                          "within the smallest bound that gives them, up to --max-error or 5 "
                          "voxel steps; every guarantee kept")
          ->check(CLI::PositiveNumber);
  CLI::Option* max_error =
      command->add_option("--max-error", options.finish_options.max_error_mm,
                          "Type merging within this distance in mm of the voxels' marching-cubes "
                          "surface, two-sided over both surfaces, then bounded collapses within "
                          "it (default: type merging within half a voxel)")
          ->check(CLI::PositiveNumber);
  command->add_flag("--merge-only", options.finish_options.merge_only,
                    "With --max-error: type merging alone, without the collapses (a fraction of "
                    "the time, more triangles)")
      ->needs(max_error)
      ->excludes(reduce_to);
  command->add_option("--decimator", options.removed_decimator,
                      "Removed: --reduce-to and --max-error are type merging itself now");
  command->add_option("--denoise", options.denoise, "Denoise first: none, gaussian, median, bilateral")
      ->check(CLI::IsMember({"none", "gaussian", "median", "bilateral"}));
  command->add_option("--voxel-size", options.voxel_size_mm,
                      "Resample to isotropic voxels of this size in mm first")
      ->check(CLI::PositiveNumber);
  command->add_flag("--crop-tissue", options.crop_to_tissue,
                    "Crop to the bounding box of the body (> -400 HU) first");
  command->add_option("--crop-mm", options.crop_box_mm,
                      "Crop to an LPS box X0,Y0,Z0,X1,Y1,Z1 in mm first (e.g. to leave out the "
                      "face: keep y above the face's front)")
      ->delimiter(',')
      ->expected(6);
  auto* remove_table = command->add_flag(
      "--remove-table", options.remove_table,
      "Clear everything outside the body (scanner table, rails, mattress) to air first; "
      "default with presets");
  command->add_flag("--keep-table", options.keep_table, "Do not remove the table")
      ->excludes(remove_table);
  command->add_flag("--preview", options.preview, "Also write a shaded PNG beside each STL");
  command->add_flag("--ascii", options.ascii_stl, "ASCII STL instead of binary");
  command->add_option("--space", options.space,
                      "Coordinates of the output: lps (DICOM, 3D Slicer's STL default) or ras")
      ->check(CLI::IsMember({"lps", "ras"}));
  command->add_flag("--center", options.center,
                    "Move the surfaces, all by one offset, so their joint bounding box is "
                    "centred on 0 (for printing)");
  command->add_flag("--show-descriptions", options.show_descriptions,
                    "Put the series' SeriesDescription in the report (free text that can "
                    "identify the patient; left out by default)");
}

ConversionShape conversion_shape(const ConvertOptions& options) {
  ConversionShape shape;
  const std::vector<SurfaceSpec> specs = surface_specs(options);
  shape.surfaces = specs.size();
  for (const SurfaceSpec& spec : specs) shape.window_surfaces += spec.hi.has_value() ? 1 : 0;
  shape.reduces = options.finish_options.reduce_to_triangles > 0 ||
                  options.finish_options.max_error_mm > 0;
  shape.hollows = options.hollow_mm > 0;
  return shape;
}

int run_convert(const ConvertOptions& options, std::ostream& log) {
  check_reduction_options(options);
  if (label_mode_requested(options)) return run_label_convert(options, log);
  const auto run_start = Clock::now();
  // Progress for people at a terminal; scripts and logs (stderr not a TTY) get only results.
  const bool interactive = ::isatty(STDERR_FILENO) == 1;
  auto progress = [&](const std::string& what) {
    if (interactive) log << "... " << what << "\n" << std::flush;
  };
  std::vector<SurfaceSpec> specs = surface_specs(options);
  const ConversionShape shape = conversion_shape(options);
  std::vector<std::string> notes;  // what was adapted to the data, for the log and the report
  // A stated bound on every run, not only when asked: three quarters of the physical memory
  // by default.
  std::uint64_t max_memory = default_memory_budget();
  if (!options.max_memory.empty()) {
    try {
      max_memory = parse_memory_size(options.max_memory);
    } catch (const std::invalid_argument& error) {
      throw CommandError{kExitUsage, error.what()};
    }
  }
  if (specs.size() > 1 && !writes_package(options)) {
    std::error_code error;
    fs::create_directories(options.output, error);
    if (error) throw CommandError{kExitOutputFailed, "cannot create " + options.output};
  } else {
    try {
      io::mesh_format_for(output_path(options, specs[0], 1), options.ascii_stl);
    } catch (const std::invalid_argument& error) {
      throw CommandError{kExitUsage, error.what()};
    }
    const fs::path parent = output_path(options, specs[0], 1).parent_path();
    if (!parent.empty() && !fs::is_directory(parent)) {
      throw CommandError{kExitOutputFailed, "output folder " + parent.string() + " does not exist"};
    }
  }

  ordered_json report = {{"tool", "typemerge"}, {"version", kVersion}};
  const auto load_start = Clock::now();
  progress("reading " + options.input.input);
  LoadedInput input = load_input(options.input, options.series_id, [&](const InputShape& s) {
    const std::uint64_t voxels = working_voxels(s.grid_size(), s.spacing_mm(), options.voxel_size_mm);
    ConversionShape series_shape = shape;
    series_shape.int16_samples = s.int16_samples;
    const std::uint64_t estimate = conversion_memory_estimate(voxels, series_shape);
    if (estimate > max_memory) {
      throw CommandError{kExitInputRefused,
                         "series " + s.id + " would need about " + format_megabytes(estimate) +
                             " to convert, more than --max-memory " + format_megabytes(max_memory)};
    }
    // From here on (pixels, preprocessing, meshes) the bound is hard. The scan before it reads
    // headers only, each bounded by the per-file checks of the header reader.
    limit_address_space(max_memory);
  });
  const dicom::SeriesInfo& series = *input.series;
  dicom::LoadedSeries& loaded = input.loaded;
  const double load_ms = ms_since(load_start);
  for (const auto& w : loaded.warnings) log << "warning: " << w << "\n";
  const auto& size = loaded.volume.size();
  report["input"] = {{"series", series.id},
                     {"size", {size.nx, size.ny, size.nz}},
                     {"spacing_mm", {loaded.volume.geometry().spacing(0),
                                     loaded.volume.geometry().spacing(1),
                                     series.geometry.slice_step_mm}},
                     {"tilt_degrees", loaded.tilt_degrees},
                     {"hu_range", {loaded.min_hu, loaded.max_hu}},
                     {"warnings", loaded.warnings},
                     {"load_ms", load_ms}};
  // Free text that can identify the patient: only on request.
  if (options.show_descriptions) report["input"]["description"] = series.description;

  // Preprocessing, in a fixed order: table removal (on the data as acquired), crop (less to
  // filter), denoise, resample.
  core::Volume volume = std::move(loaded.volume);
  ordered_json steps = ordered_json::array();
  const bool any_preset = !options.presets.empty();
  // Steps that assume Hounsfield units (table removal, the tissue crop's -400 HU) are skipped
  // or adapted, with a note, for another modality or for values that do not look like HU.
  const std::string not_hu_reason = not_hounsfield_reason(series, loaded);
  const std::string units = not_hu_reason.empty() ? " HU" : "";
  auto note = [&](const std::string& text) {
    log << "note: " << text << "\n";
    notes.push_back(text);
  };
  try {
    if ((options.remove_table || (any_preset && !options.keep_table)) && !not_hu_reason.empty()) {
      note("table removal skipped: " + not_hu_reason + ", and it works in HU");
      steps.push_back({{"step", "remove_outside_body"}, {"skipped", true},
                       {"description", "skipped: " + not_hu_reason}});
    } else if (options.remove_table || (any_preset && !options.keep_table)) {
      const auto start = Clock::now();
      auto step = preprocess::remove_outside_body(std::move(volume));
      volume = std::move(step.volume);
      for (const auto& w : step.record.warnings) log << "warning: " << w << "\n";
      steps.push_back(record_json(step.record, ms_since(start)));
    }
    if (options.crop_box_mm.size() == 6) {
      const auto start = Clock::now();
      const auto& b = options.crop_box_mm;
      preprocess::PatientBox box{{std::min(b[0], b[3]), std::min(b[1], b[4]), std::min(b[2], b[5])},
                                 {std::max(b[0], b[3]), std::max(b[1], b[4]), std::max(b[2], b[5])}};
      auto step = preprocess::crop_to_patient_box(volume, box);
      volume = std::move(step.volume);
      for (const auto& w : step.record.warnings) log << "warning: " << w << "\n";
      steps.push_back(record_json(step.record, ms_since(start)));
    }
    if (options.crop_to_tissue) {
      const auto start = Clock::now();
      preprocess::TissueCropOptions crop;
      if (!not_hu_reason.empty()) {
        crop.threshold_hu = static_cast<float>(preprocess::otsu_threshold(volume).threshold);
        note("tissue crop at Otsu's threshold " + preprocess::detail::format_number(crop.threshold_hu) +
             " instead of -400 HU: " + not_hu_reason);
      }
      auto step = preprocess::crop_to_tissue(volume, crop);
      volume = std::move(step.volume);
      steps.push_back(record_json(step.record, ms_since(start)));
    }
    if (options.denoise != "none") {
      const auto start = Clock::now();
      preprocess::StepResult step =
          options.denoise == "gaussian" ? preprocess::gaussian_filter(std::move(volume))
          : options.denoise == "median" ? preprocess::median_filter(std::move(volume))
                                        : preprocess::bilateral_filter(std::move(volume));
      volume = std::move(step.volume);
      steps.push_back(record_json(step.record, ms_since(start)));
    }
    if (options.voxel_size_mm > 0) {
      const auto start = Clock::now();
      preprocess::IsotropicOptions isotropic;
      isotropic.voxel_size_mm = options.voxel_size_mm;
      auto step = preprocess::resample_isotropic(std::move(volume), isotropic);
      volume = std::move(step.volume);
      steps.push_back(record_json(step.record, ms_since(start)));
    }
  } catch (const std::invalid_argument& error) {
    throw CommandError{kExitUsage, error.what()};
  }
  report["preprocess"] = steps;

  PipelineOptions pipeline;
  pipeline.algorithm = options.algorithm;
  pipeline.close_borders = !options.open_borders;
  pipeline.threads = options.threads;
  pipeline.finish = options.finish_options;
  pipeline.check_intersections = options.check_intersections;
  pipeline.hollow_mm = options.hollow_mm;
  pipeline.finish.enabled = options.finish != "none";
  pipeline.measure_distance = !options.report.empty() && options.report_distances;
  pipeline.finish.min_component_mm3 = options.min_component_mm3;
  if (options.fill_cavities) pipeline.finish.fill_cavities = true;
  report["parameters"] = {{"algorithm", options.algorithm},
                          {"close_borders", pipeline.close_borders},
                          {"finish", options.finish},
                          {"smooth_iterations", pipeline.finish.smooth_iterations},
                          {"reduce_to", pipeline.finish.reduce_to_triangles},
                          {"max_error_mm", pipeline.finish.max_error_mm},
                          {"check_intersections", options.check_intersections},
                          {"hollow_mm", options.hollow_mm > 0 ? ordered_json(options.hollow_mm)
                                                              : ordered_json(nullptr)}};

  // --iso auto: Otsu's threshold of the volume as it will be meshed.
  for (SurfaceSpec& spec : specs) {
    if (!spec.auto_iso) continue;
    const auto start = Clock::now();
    preprocess::OtsuThreshold otsu;
    try {
      otsu = preprocess::otsu_threshold(volume);
    } catch (const std::invalid_argument& error) {
      throw CommandError{kExitInputRefused, std::string("--iso auto: ") + error.what()};
    }
    const std::string value = preprocess::detail::format_number(otsu.threshold);
    spec.lo = otsu.threshold;
    spec.label = "iso auto (Otsu) " + value + units;
    report["auto_iso"] = {{"method", "otsu"},
                          {"threshold", otsu.threshold},
                          {"units", units.empty() ? "volume values" : "HU"},
                          {"lower_class_mean", otsu.lower_mean},
                          {"upper_class_mean", otsu.upper_mean},
                          {"upper_class_fraction", otsu.upper_fraction},
                          {"separability", otsu.separability},
                          {"bin_width", otsu.bin_width},
                          {"ms", ms_since(start)}};
    log << "iso auto: Otsu's threshold " << value << units << " (class means "
        << preprocess::detail::format_number(otsu.lower_mean) << " and "
        << preprocess::detail::format_number(otsu.upper_mean) << units << ")\n";
  }
  report["notes"] = notes;

  ordered_json surfaces = ordered_json::array();
  // Every refusal before any work; then the surfaces, which are independent, are made
  // concurrently (each with the core's threads too): one surface's serial steps (checks,
  // finishing) overlap the other's extraction. Results are used in order, so outputs, report
  // and messages do not depend on scheduling.
  for (const SurfaceSpec& spec : specs) check_tissue(volume, loaded.min_hu, loaded.max_hu, spec);
  // Nothing here reads the volume after its surfaces: the last of them to read it frees it
  // (make_surface). Declared before `pending`, whose futures wait for their surfaces.
  VolumeReaders readers(volume, specs.size());
  std::vector<std::future<SurfaceResult>> pending;
  for (const SurfaceSpec& spec : specs) {
    progress("extracting and finishing " + spec.label);
    auto make = [&volume, &pipeline, spec, &readers] {
      return make_surface(volume, spec, pipeline, &readers);
    };
    try {
      pending.push_back(std::async(std::launch::async, make));
    } catch (const std::system_error&) {
      // No thread to be had (a tight --max-memory): make it when its result is needed.
      pending.push_back(std::async(std::launch::deferred, make));
    }
  }
  // Every surface before any file: one frame for --center, one package for .3mf, and no
  // outputs of a run that fails on a later surface.
  std::vector<SurfaceResult> results;
  for (std::size_t s = 0; s < specs.size(); ++s) {
    const SurfaceSpec& spec = specs[s];
    results.push_back(pending[s].get());
    const SurfaceResult& result = results.back();
    if (result.mesh.empty()) {
      throw CommandError{kExitInputRefused,
                         result.steps.size() > 1
                             ? "the surface of " + spec.label + " was removed by finishing: every "
                               "component encloses less than the minimum volume (see "
                               "--min-component, --finish none)"
                             : "no surface for " + spec.label};
    }
  }
  const std::string space = options.space == "ras" ? "RAS" : "LPS";
  const std::string comment = std::string("typemerge ") + kVersion + " SPACE=" + space +
                              (options.center ? " CENTERED" : "");
  std::vector<double> write_ms(specs.size(), 0.0);
  std::vector<std::optional<std::size_t>> crossings(specs.size());  // with --check-intersections
  try {
    for (std::size_t s = 0; s < specs.size(); ++s) {
      // The preview always shows the LPS surface, so its views are anatomical.
      if (options.preview) {
        io::write_preview_png(results[s].mesh, preview_path(options, specs[s], specs.size()));
      }
      to_output_space(results[s].mesh, options);
    }
    if (options.center) center_together(results);
    for (std::size_t s = 0; s < specs.size(); ++s) {
      if (!options.check_intersections) continue;
      // On the floats as written (after --space / --center), which are what a slicer reads.
      crossings[s] = core::find_self_intersections(results[s].mesh).pairs.size();
      if (*crossings[s] > 0) {
        results[s].warnings.push_back(std::to_string(*crossings[s]) +
                                      " pair(s) of crossing triangles in the output");
      }
    }
    if (writes_package(options)) {
      const auto write_start = Clock::now();
      std::vector<io::ThreeMfPart> parts;
      for (std::size_t s = 0; s < specs.size(); ++s) {
        parts.push_back({&results[s].mesh, specs[s].name, specs[s].srgb});
      }
      io::write_3mf(parts, options.output, comment);
      // The package is one write: each surface is charged its share.
      std::fill(write_ms.begin(), write_ms.end(), ms_since(write_start) / double(specs.size()));
    } else {
      for (std::size_t s = 0; s < specs.size(); ++s) {
        const auto write_start = Clock::now();
        const fs::path path = output_path(options, specs[s], specs.size());
        io::write_mesh(results[s].mesh, path, io::mesh_format_for(path, options.ascii_stl),
                       comment);
        write_ms[s] = ms_since(write_start);
      }
    }
  } catch (const std::invalid_argument& error) {
    throw CommandError{kExitUsage, error.what()};
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitOutputFailed, error.what()};
  }

  for (std::size_t s = 0; s < specs.size(); ++s) {
    const SurfaceSpec& spec = specs[s];
    const SurfaceResult& result = results[s];
    const fs::path output = output_path(options, spec, specs.size());
    for (const auto& w : result.warnings) log << "warning: " << spec.name << ": " << w << "\n";

    ordered_json step_list = ordered_json::array();
    for (const auto& step : result.steps) {
      ordered_json details = ordered_json::object();
      for (const auto& [key, value] : step.details) details[key] = value;
      step_list.push_back({{"step", step.step}, {"ms", step.milliseconds},
                           {"check_ms", step.check_milliseconds},
                           {"triangles", step.triangles}, {"details", details},
                           {"validity", check_json(step.check)}});
    }
    const core::MeshCheck& final_check = result.steps.back().check;
    ordered_json hollow = nullptr;
    std::string hollow_text;
    if (result.hollow) {
      const HollowSummary& h = *result.hollow;
      const double percent = h.outer_volume > 0 ? 100.0 * h.hollow_volume / h.outer_volume : 0.0;
      hollow = {{"wall_mm", h.wall_mm},
                {"outer_volume_ml", h.outer_volume / 1000.0},
                {"inner_volume_ml", h.hollow_volume / 1000.0},
                {"material_volume_ml", final_check.volume / 1000.0},
                {"saved_ml", h.hollow_volume / 1000.0},
                {"saved_percent", percent},
                {"inner_components", h.inner_components},
                {"inner_components_dropped_outside", h.dropped_outside},
                {"inner_components_dropped_small", h.dropped_small}};
      char text[160];
      std::snprintf(text, sizeof text, ", hollow (wall %g mm): %.1f mL of %.1f saved (%.0f%%)",
                    h.wall_mm, h.hollow_volume / 1000.0, h.outer_volume / 1000.0, percent);
      hollow_text = text;
    }
    const core::BoundingBox box = core::bounding_box(result.mesh);
    char colour[8];
    std::snprintf(colour, sizeof colour, "#%02X%02X%02X", spec.srgb[0], spec.srgb[1],
                  spec.srgb[2]);
    surfaces.push_back({{"name", spec.name},
                        {"label", spec.label},
                        {"hu_lo", spec.lo},
                        {"hu_hi", spec.hi ? ordered_json(*spec.hi) : ordered_json(nullptr)},
                        {"output", output.filename().string()},
                        {"display_color",
                         writes_package(options) ? ordered_json(colour) : ordered_json(nullptr)},
                        {"triangles", result.mesh.triangles.size()},
                        {"volume_ml", final_check.volume / 1000.0},
                        {"area_mm2", final_check.area},
                        {"bounding_box_lps_mm", {box.min, box.max}},
                        {"hollow", hollow},
                        {"reduction", reduction_json(result)},
                        {"distance_to_marching_cubes", distance_json(result)},
                        {"validity", check_json(final_check)},
                        {"self_intersecting_pairs",
                         crossings[s] ? ordered_json(*crossings[s]) : ordered_json(nullptr)},
                        {"steps", step_list},
                        {"write_ms", write_ms[s]},
                        {"warnings", result.warnings}});
    const std::string crossing_text =
        !crossings[s] ? ""
        : *crossings[s] == 0
            ? ", no crossing triangles"
            : ", " + std::to_string(*crossings[s]) + " CROSSING pair(s)";
    std::string reduction_text;
    if (result.reduction && result.reduction->target_triangles > 0) {
      char text[160];
      std::snprintf(text, sizeof text, ", within %.3g mm%s", result.reduction->bound_mm,
                    result.reduction->target_met ? "" : " (--reduce-to NOT MET)");
      reduction_text = text;
    } else if (result.reduction) {
      reduction_text = ", within " + preprocess::detail::format_number(result.reduction->bound_mm) +
                       " mm";
    }
    char line[640];
    std::snprintf(line, sizeof line, "%s: %zu triangles%s, %.1f mL, %s%s%s, written to %s\n",
                  spec.label.c_str(), result.mesh.triangles.size(), reduction_text.c_str(),
                  final_check.volume / 1000.0,
                  final_check.closed_manifold() ? "closed manifold" : "NOT closed manifold",
                  crossing_text.c_str(), hollow_text.c_str(), output.string().c_str());
    log << line;
  }
  report["surfaces"] = surfaces;
  report["total_ms"] = ms_since(run_start);
  if (!options.report.empty()) {
    try {
      io::AtomicFile file(options.report);
      file.write(report.dump(2) + "\n");
      file.commit();
    } catch (const std::runtime_error& error) {
      throw CommandError{kExitOutputFailed, error.what()};
    }
  }
  return kExitOk;
}

}  // namespace typemerge::app
