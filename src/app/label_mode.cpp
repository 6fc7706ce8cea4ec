#include "app/label_mode.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <ostream>
#include <set>
#include <vector>

#include "app/exit_codes.h"
#include "app/input_kind.h"
#include "app/label_names.h"
#include "app/label_surfaces.h"
#include "app/memory_budget.h"
#include "app/surface_pipeline.h"
#include "app/version.h"
#include "app/volume_file_input.h"
#include "core/self_intersections.h"
#include "io/atomic_file.h"
#include "io/mesh_writers.h"
#include "io/three_mf_writer.h"
#include "preprocess/denoise.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

// A map that does not say it holds labels, converted with every label, must look like it:
// with more than kManyLabels values, at least kMinLabelCoherence of its labelled voxels have
// their own value beside them (label_coherence). Labels w voxels across give about
// (w − 1) / w, so even two-voxel-thin structures give 0.5; grey values little (an MR: 0.05).
constexpr std::size_t kManyLabels = 64;
constexpr double kMinLabelCoherence = 0.25;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// One label to extract.
struct LabelPart {
  core::Segment segment;
  LabelExtent extent;
  std::string name;
  std::array<std::uint8_t, 3> srgb{};
  std::string stem;
};

// "all" → nullopt; "1,3,7" → {1, 3, 7}.
std::optional<std::set<std::int32_t>> parse_selection(const std::string& text) {
  if (text == "all") return std::nullopt;
  std::set<std::int32_t> labels;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    std::int32_t label = 0;
    const char* begin = text.data() + at;
    const char* end = text.data() + comma;
    const auto parsed = std::from_chars(begin, end, label);
    if (parsed.ec != std::errc() || parsed.ptr != end || label <= 0) {
      throw CommandError{kExitUsage, "--labels wants 'all' or positive label numbers N[,N...]"};
    }
    labels.insert(label);
    at = comma + 1;
  }
  return labels;
}

ordered_json check_json(const core::MeshCheck& check) {
  return {{"closed_manifold", check.closed_manifold()},
          {"boundary_edges", check.boundary_edges},
          {"non_manifold_edges", check.non_manifold_edges},
          {"non_manifold_vertices", check.non_manifold_vertices},
          {"inconsistent_edges", check.inconsistent_edges},
          {"components", check.components},
          {"euler_characteristic", check.euler_characteristic}};
}

double voxel_volume_mm3(const core::IndexToPatient& g) { return std::abs(g.determinant()); }

bool writes_package(const std::string& output) {
  const std::string extension = fs::path(output).extension().string();
  return extension == ".3mf" || extension == ".3MF";
}

}  // namespace

namespace detail {

core::Volume label_field(const core::Volume& layer, std::int32_t label, const LabelExtent& extent,
                         double sigma_mm) {
  const core::IndexToPatient& g = layer.geometry();
  const double min_spacing = std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
  // The Gaussian's support (3σ, as preprocess::gaussian_filter truncates) plus one voxel.
  const auto pad = static_cast<std::int64_t>(1 + std::ceil(3.0 * sigma_mm / min_spacing));
  std::array<std::int64_t, 3> lo{}, n{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = extent.min[a] - pad;
    n[a] = extent.max[a] - extent.min[a] + 1 + 2 * pad;
  }
  core::IndexToPatient box = g;
  box.origin = g.apply(double(lo[0]), double(lo[1]), double(lo[2]));
  core::Volume field({n[0], n[1], n[2]}, box);
  const auto& size = layer.size();
  const float value = static_cast<float>(label);
  // One pass over the box's part inside the layer, row by row and without branches: the
  // indicator, and the label's voxels as a byte mask for the clamp (a quarter of a copy).
  const std::int64_t i0 = std::max<std::int64_t>(0, -lo[0]);
  const std::int64_t i1 = std::min<std::int64_t>(n[0], size.nx - lo[0]);
  auto& out = field.samples();
  std::vector<std::uint8_t> member(out.size(), 0);
  layer.visit([&](const auto* samples) {  // float or int16 storage, read as floats
    for (std::int64_t k = 0; k < n[2]; ++k) {
      const std::int64_t z = lo[2] + k;
      if (z < 0 || z >= size.nz) continue;
      for (std::int64_t j = 0; j < n[1]; ++j) {
        const std::int64_t y = lo[1] + j;
        if (y < 0 || y >= size.ny || i1 <= i0) continue;
        const auto* row = samples + static_cast<std::size_t>(lo[0] + size.nx * (y + size.ny * z));
        const auto at = static_cast<std::size_t>(n[0] * (j + n[1] * k));
        for (std::int64_t i = i0; i < i1; ++i) {
          const bool in = static_cast<float>(row[i]) == value;
          out[at + static_cast<std::size_t>(i)] = in ? 1.0f : 0.0f;
          member[at + static_cast<std::size_t>(i)] = in ? 1 : 0;
        }
      }
    }
  });
  if (sigma_mm <= 0) return field;
  preprocess::GaussianOptions gaussian;
  gaussian.sigma_mm = sigma_mm;
  gaussian.truncate = 3.0;
  core::Volume smooth = preprocess::gaussian_filter(std::move(field), gaussian).volume;
  const float inside = 0.5f + kClampMargin, outside = 0.5f - kClampMargin;
  auto& s = smooth.samples();
  for (std::size_t v = 0; v < s.size(); ++v) {
    s[v] = member[v] != 0 ? std::max(s[v], inside) : std::min(s[v], outside);
  }
  return smooth;
}

}  // namespace detail

void add_label_options(CLI::App& command, CLI::App& surface_group, ConvertOptions& options) {
  auto* labels = command.add_option(
      "--labels", options.labels,
      "Label mode for an integer NIfTI/NRRD label map: 'all' or N[,N...]; one closed surface "
      "per label (0 is background), named and coloured in a .3mf, or OUT/<name>.stl each. "
      "A .seg.nrrd is in label mode without it");
  for (const char* name : {"--preset", "--iso", "--window"}) {
    if (CLI::Option* other = surface_group.get_option_no_throw(name)) labels->excludes(other);
  }
  command.add_option("--label-names", options.label_names,
                     "Label names and colours: 3D Slicer .ctbl, FreeSurfer LUT, ITK-SNAP label "
                     "description or 'index;name' lines (over names in the file)");
  command
      .add_option("--label-smoothing", options.label_smoothing_mm,
                  "Gaussian sigma in mm applied to each label's mask before extraction "
                  "(default: half the smallest voxel spacing; 0: the raw voxel surface)")
      ->check(CLI::NonNegativeNumber);
}

bool label_mode_requested(const ConvertOptions& options) {
  if (!options.labels.empty()) return true;
  // Only a segmentation file (Slicer's Segment keys) decides by itself; a NIfTI whose intent
  // says "label" is still converted as asked (--iso on a label map is a union of labels).
  const InputKind kind = input_kind(options.input.input);
  if (kind == InputKind::seg) return true;  // a DICOM SEG holds segments only
  if (kind != InputKind::nrrd) return false;
  std::error_code error;
  if (!fs::is_regular_file(options.input.input, error)) return false;
  try {
    return read_volume_file_shape(options.input.input, kind).segmentation;
  } catch (const CommandError&) {
    return false;  // the grey path reports the reason
  }
}

int run_label_convert(const ConvertOptions& options, std::ostream& log) {
  const auto run_start = Clock::now();
  if (!options.presets.empty() || !options.iso.empty() || !options.window.empty()) {
    throw CommandError{kExitUsage,
                       "this input is a segmentation: label mode extracts its segments; "
                       "--preset, --iso and --window do not apply"};
  }
  if (options.hollow_mm > 0 || options.voxel_size_mm > 0 || options.denoise != "none" ||
      options.crop_to_tissue || !options.crop_box_mm.empty() || options.remove_table ||
      options.preview) {
    throw CommandError{kExitUsage,
                       "label mode takes no preprocessing (--hollow, --voxel-size, --denoise, "
                       "--crop-*, --remove-table) and writes no --preview"};
  }
  const auto selection = parse_selection(options.labels.empty() ? "all" : options.labels);
  const InputKind kind = input_kind(options.input.input);
  if (kind == InputKind::dicom) {
    throw CommandError{kExitUsage, "--labels reads NIfTI or NRRD label maps, not DICOM series"};
  }
  std::uint64_t max_memory = default_memory_budget();
  if (!options.max_memory.empty()) {
    try {
      max_memory = parse_memory_size(options.max_memory);
    } catch (const std::invalid_argument& error) {
      throw CommandError{kExitUsage, error.what()};
    }
  }
  std::map<std::int32_t, LabelName> table;
  if (!options.label_names.empty()) table = read_label_names(options.label_names);

  // The header alone: the memory estimate before any data is read.
  const VolumeFileShape shape = read_volume_file_shape(options.input.input, kind);
  const std::uint64_t voxels = static_cast<std::uint64_t>(shape.size.voxels()) * shape.layers;
  const std::uint64_t estimate = conversion_memory_estimate(voxels, {});
  if (estimate > max_memory) {
    throw CommandError{kExitInputRefused,
                       "this label map would need about " + format_megabytes(estimate) +
                           " to convert, more than --max-memory " + format_megabytes(max_memory)};
  }
  limit_address_space(max_memory);
  const auto load_start = Clock::now();
  VolumeFile file = read_volume_file(options.input.input, kind);
  const double load_ms = ms_since(load_start);
  for (const auto& w : file.warnings) log << "warning: " << w << "\n";
  if (!file.values.all_integer) {
    throw CommandError{kExitInputRefused,
                       "label mode needs integer labels, and this map holds fractional values "
                       "(a probability map? extract it with --iso)"};
  }
  if (file.values.min < 0 || file.values.max > float(1 << 24)) {
    throw CommandError{kExitInputRefused,
                       "label mode needs labels from 0 to 2^24; this map "
                       "holds values outside"};
  }
  core::LabelVolume& content = file.content;
  const core::IndexToPatient& geometry = content.layers.front().geometry();

  // Labels and boxes, one pass per layer; the file's segments, else every label present.
  std::vector<std::map<std::int32_t, LabelExtent>> census;
  for (const core::Volume& layer : content.layers) census.push_back(label_census(layer));
  // An image of grey values (an MR, a CT) read as labels would give a surface for every grey
  // value, after minutes: refused at once where many values change from voxel to voxel,
  // unless the file says it holds labels or the labels are named.
  if (!selection && !shape.segmentation && census.front().size() > kManyLabels) {
    const double coherence = label_coherence(content.layers.front());
    if (coherence < kMinLabelCoherence) {
      throw CommandError{
          kExitInputRefused,
          "this map does not look like labels: " + std::to_string(census.front().size()) +
              " values, and " + std::to_string(static_cast<int>(std::lround(coherence * 100))) +
              " % of its voxels above 0 have the same value beside them (most, in a label "
              "map): an image of grey values? Extract a surface with --iso VALUE, or name the "
              "labels to convert: --labels N[,N...]"};
    }
  }
  if (content.segments.empty()) {
    for (const auto& [label, extent] : census.front()) {
      content.segments.push_back({label, 0, "", std::nullopt});
    }
  }
  std::vector<LabelPart> parts;
  std::set<std::int32_t> found;
  for (const core::Segment& segment : content.segments) {
    if (selection && selection->count(segment.label) == 0) continue;
    const auto it = census[segment.layer].find(segment.label);
    if (it == census[segment.layer].end()) {
      log << "warning: label " << segment.label << " has no voxels: no surface\n";
      continue;
    }
    found.insert(segment.label);
    LabelPart part{segment, it->second, {}, {}, {}};
    const auto named = table.find(segment.label);
    part.name = named != table.end() && !named->second.name.empty() ? named->second.name
                : !segment.name.empty()                             ? segment.name
                                        : "label-" + std::to_string(segment.label);
    part.srgb = named != table.end() && named->second.srgb ? *named->second.srgb
                : segment.srgb                             ? *segment.srgb
                                                           : palette_colour(parts.size());
    parts.push_back(std::move(part));
  }
  if (selection) {
    for (std::int32_t label : *selection) {
      if (found.count(label) == 0) {
        throw CommandError{kExitInputRefused, "label " + std::to_string(label) +
                                                  " is not in this map (see `typemerge info`)"};
      }
    }
  }
  if (parts.empty())
    throw CommandError{kExitInputRefused, "no labels in this map (only background)"};
  {
    std::vector<std::string> names;
    for (const LabelPart& p : parts) names.push_back(p.name);
    const auto stems = safe_unique_stems(names);
    for (std::size_t p = 0; p < parts.size(); ++p) parts[p].stem = stems[p];
  }

  const bool package = writes_package(options.output);
  const bool single_file =
      !package && parts.size() == 1 && fs::path(options.output).has_extension();
  if (!package && !single_file) {
    std::error_code error;
    fs::create_directories(options.output, error);
    if (error) throw CommandError{kExitOutputFailed, "cannot create " + options.output};
  }

  const double min_spacing =
      std::min({geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)});
  const double sigma_mm = options.label_smoothing_mm.value_or(0.5 * min_spacing);
  PipelineOptions pipeline;
  pipeline.algorithm = options.algorithm;
  pipeline.close_borders = true;
  pipeline.threads = options.threads;
  pipeline.finish = options.finish_options;
  pipeline.finish.enabled = options.finish != "none";
  pipeline.finish.min_component_mm3 = options.min_component_mm3;
  if (options.fill_cavities) pipeline.finish.fill_cavities = true;
  pipeline.check_intersections = options.check_intersections;

  // Labels on all threads at once (label_surfaces.h: the same bytes for any thread count).
  std::vector<LabelTask> tasks;
  for (const LabelPart& part : parts) {
    tasks.push_back({&content.layers[part.segment.layer],
                     part.segment.label,
                     part.extent,
                     {part.stem, "label " + std::to_string(part.segment.label), detail::kLabelIso,
                      std::nullopt, false, 0, false, false, part.srgb}});
  }
  std::vector<LabelSurface> made =
      extract_label_surfaces(tasks, sigma_mm, pipeline, options.threads);
  std::vector<SurfaceResult> results;
  std::vector<double> extract_ms;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (made[p].result.mesh.empty()) {
      throw CommandError{kExitInputRefused, "the surface of label " +
                                                std::to_string(parts[p].segment.label) +
                                                " was removed by finishing (see --min-component)"};
    }
    results.push_back(std::move(made[p].result));
    extract_ms.push_back(made[p].milliseconds);
  }

  const std::string comment = std::string("typemerge ") + kVersion +
                              " SPACE=" + (options.space == "ras" ? "RAS" : "LPS") +
                              (options.center ? " CENTERED" : "");
  if (options.space == "ras") {
    for (SurfaceResult& r : results) {
      for (auto& p : r.mesh.positions) {
        p[0] = -p[0];
        p[1] = -p[1];
      }
      for (auto& n : r.mesh.normals) {
        n[0] = -n[0];
        n[1] = -n[1];
      }
    }
  }
  if (options.center) {
    // One offset for all parts, centring their joint box on 0 (they stay in one frame).
    core::BoundingBox joint;
    for (const SurfaceResult& r : results) {
      const core::BoundingBox box = core::bounding_box(r.mesh);
      for (int c = 0; c < 3; ++c) {
        joint.min[c] = std::min(joint.min[c], box.min[c]);
        joint.max[c] = std::max(joint.max[c], box.max[c]);
      }
    }
    std::array<float, 3> offset{};
    for (int c = 0; c < 3; ++c) offset[c] = 0.5f * (float(joint.min[c]) + float(joint.max[c]));
    for (SurfaceResult& r : results) {
      for (auto& p : r.mesh.positions) {
        for (int c = 0; c < 3; ++c) p[c] -= offset[c];
      }
    }
  }
  std::vector<std::optional<std::size_t>> crossings(parts.size());
  if (options.check_intersections) {
    for (std::size_t p = 0; p < parts.size(); ++p) {
      crossings[p] = core::find_self_intersections(results[p].mesh).pairs.size();
    }
  }
  std::vector<fs::path> outputs;
  try {
    if (package) {
      std::vector<io::ThreeMfPart> package_parts;
      for (std::size_t p = 0; p < parts.size(); ++p) {
        package_parts.push_back({&results[p].mesh, parts[p].name, parts[p].srgb});
        outputs.push_back(options.output);
      }
      io::write_3mf(package_parts, options.output, comment);
    } else {
      for (std::size_t p = 0; p < parts.size(); ++p) {
        const fs::path path = single_file ? fs::path(options.output)
                                          : fs::path(options.output) / (parts[p].stem + ".stl");
        io::write_mesh(results[p].mesh, path, io::mesh_format_for(path, options.ascii_stl),
                       comment);
        outputs.push_back(path);
      }
    }
  } catch (const std::invalid_argument& error) {
    throw CommandError{kExitUsage, error.what()};
  } catch (const std::runtime_error& error) {
    throw CommandError{kExitOutputFailed, error.what()};
  }

  const double voxel_mm3 = voxel_volume_mm3(geometry);
  ordered_json labels_json = ordered_json::array();
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const LabelPart& part = parts[p];
    const SurfaceResult& result = results[p];
    const core::MeshCheck& check = result.steps.back().check;
    const core::BoundingBox box = core::bounding_box(result.mesh);
    char colour[8];
    std::snprintf(colour, sizeof colour, "#%02X%02X%02X", part.srgb[0], part.srgb[1], part.srgb[2]);
    const double voxel_ml = double(part.extent.voxels) * voxel_mm3 / 1000.0;
    labels_json.push_back({{"label", part.segment.label},
                           {"layer", part.segment.layer},
                           {"name", part.name},
                           {"output", outputs[p].filename().string()},
                           {"display_color", colour},
                           {"voxels", part.extent.voxels},
                           {"voxel_volume_ml", voxel_ml},
                           {"volume_ml", check.volume / 1000.0},
                           {"area_mm2", check.area},
                           {"triangles", result.mesh.triangles.size()},
                           {"bounding_box_lps_mm", {box.min, box.max}},
                           {"validity", check_json(check)},
                           {"self_intersecting_pairs",
                            crossings[p] ? ordered_json(*crossings[p]) : ordered_json(nullptr)},
                           {"ms", extract_ms[p]},
                           {"warnings", result.warnings}});
    char line[512];
    std::snprintf(
        line, sizeof line,
        "label %d (%s): %zu voxels (%.2f mL), %zu triangles, %.2f mL, %s%s, written to %s\n",
        part.segment.label, part.name.c_str(), std::size_t(part.extent.voxels), voxel_ml,
        result.mesh.triangles.size(), check.volume / 1000.0,
        check.closed_manifold() ? "closed manifold" : "NOT closed manifold",
        !crossings[p]        ? ""
        : *crossings[p] == 0 ? ", no crossing triangles"
                             : ", CROSSING triangles",
        outputs[p].string().c_str());
    log << line;
    for (const auto& w : result.warnings) log << "warning: " << part.stem << ": " << w << "\n";
  }
  if (!options.report.empty()) {
    ordered_json report = {{"tool", "typemerge"}, {"version", kVersion}};
    const auto& size = shape.size;
    report["input"] = {{"format", shape.format},    {"size", {size.nx, size.ny, size.nz}},
                       {"layers", shape.layers},    {"spacing_mm", shape.spacing_mm()},
                       {"warnings", file.warnings}, {"load_ms", load_ms}};
    report["parameters"] = {{"mode", "labels"},
                            {"algorithm", options.algorithm},
                            {"label_smoothing_sigma_mm", sigma_mm},
                            {"clamp_margin", detail::kClampMargin},
                            {"iso", detail::kLabelIso},
                            {"finish", options.finish}};
    report["labels"] = labels_json;
    report["total_ms"] = ms_since(run_start);
    try {
      io::AtomicFile out(options.report);
      out.write(report.dump(2) + "\n");
      out.commit();
    } catch (const std::runtime_error& error) {
      throw CommandError{kExitOutputFailed, error.what()};
    }
  }
  return kExitOk;
}

}  // namespace typemerge::app
