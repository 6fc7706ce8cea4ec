#include "app/volume_file_info.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <ostream>

#include "app/exit_codes.h"
#include "app/label_census.h"
#include "app/volume_file_input.h"

namespace typemerge::app {
namespace {

using nlohmann::ordered_json;

constexpr std::size_t kMaxListedLabels = 1000;

struct LabelRow {
  std::int32_t label = 0;
  std::size_t layer = 0;
  std::string name;
  LabelExtent extent;
  double volume_ml = 0;
  core::Vec3 box_min{}, box_max{};
};

// The LPS box of the voxels' outer faces (index box ± ½ voxel, all 8 corners mapped).
void lps_box(const core::IndexToPatient& g, const LabelExtent& e, core::Vec3& lo, core::Vec3& hi) {
  lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
        std::numeric_limits<double>::infinity()};
  hi = {-lo[0], -lo[1], -lo[2]};
  for (int corner = 0; corner < 8; ++corner) {
    const double i = (corner & 1) ? double(e.max[0]) + 0.5 : double(e.min[0]) - 0.5;
    const double j = (corner & 2) ? double(e.max[1]) + 0.5 : double(e.min[1]) - 0.5;
    const double k = (corner & 4) ? double(e.max[2]) + 0.5 : double(e.min[2]) - 0.5;
    const core::Vec3 p = g.apply(i, j, k);
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], p[c]);
      hi[c] = std::max(hi[c], p[c]);
    }
  }
}

}  // namespace

int run_volume_file_info(const InfoOptions& options, InputKind kind, std::ostream& out) {
  VolumeFile file = read_volume_file(options.input.input, kind);
  const VolumeFileShape& shape = file.shape;
  const core::IndexToPatient& g = file.content.layers.front().geometry();
  const bool label_values =
      file.values.all_integer && file.values.min >= 0 && file.values.max <= float(1 << 24);
  std::vector<LabelRow> rows;
  bool listed = false;
  if (label_values) {
    std::vector<std::map<std::int32_t, LabelExtent>> census;
    for (const core::Volume& layer : file.content.layers) census.push_back(label_census(layer));
    std::size_t distinct = 0;
    for (const auto& c : census) distinct += c.size();
    listed = shape.segmentation || distinct <= kMaxListedLabels;
    if (listed) {
      std::vector<core::Segment> segments = file.content.segments;
      if (segments.empty()) {
        for (const auto& [label, extent] : census.front())
          segments.push_back({label, 0, "", std::nullopt});
      }
      const double voxel_mm3 = std::abs(g.determinant());
      for (const core::Segment& s : segments) {
        LabelRow row;
        row.label = s.label;
        row.layer = s.layer;
        row.name = s.name.empty() ? "label-" + std::to_string(s.label) : s.name;
        if (const auto it = census[s.layer].find(s.label); it != census[s.layer].end()) {
          row.extent = it->second;
          lps_box(g, row.extent, row.box_min, row.box_max);
        }
        row.volume_ml = double(row.extent.voxels) * voxel_mm3 / 1000.0;
        rows.push_back(row);
      }
    }
  }
  const auto& size = shape.size;
  if (options.json) {
    ordered_json doc = {{"format", shape.format},
                        {"size", {size.nx, size.ny, size.nz}},
                        {"layers", shape.layers},
                        {"spacing_mm", shape.spacing_mm()},
                        {"origin_lps_mm", g.origin},
                        {"axes_lps_mm", g.axes},
                        {"value_type", std::string(volume_file::to_string(shape.type))},
                        {"value_range", {file.values.min, file.values.max}},
                        {"segmentation", shape.segmentation},
                        {"warnings", file.warnings}};
    ordered_json labels = ordered_json::array();
    for (const LabelRow& row : rows) {
      labels.push_back(
          {{"label", row.label},
           {"layer", row.layer},
           {"name", row.name},
           {"voxels", row.extent.voxels},
           {"volume_ml", row.volume_ml},
           {"bounding_box_lps_mm", row.extent.voxels > 0 ? ordered_json({row.box_min, row.box_max})
                                                         : ordered_json(nullptr)}});
    }
    doc["labels"] = listed ? labels : ordered_json(nullptr);
    out << doc.dump(2) << "\n";
    return kExitOk;
  }
  char text[256];
  std::snprintf(text, sizeof text, "%s file: %lldx%lldx%lld voxels%s, %.3f x %.3f x %.3f mm, %s\n",
                shape.format.c_str(), static_cast<long long>(size.nx),
                static_cast<long long>(size.ny), static_cast<long long>(size.nz),
                shape.layers > 1 ? (", " + std::to_string(shape.layers) + " layers").c_str() : "",
                g.spacing(0), g.spacing(1), g.spacing(2),
                std::string(volume_file::to_string(shape.type)).c_str());
  out << text;
  std::snprintf(text, sizeof text, "  origin (LPS mm) %.3f %.3f %.3f; values %g..%g\n", g.origin[0],
                g.origin[1], g.origin[2], double(file.values.min), double(file.values.max));
  out << text;
  for (int a = 0; a < 3; ++a) {
    std::snprintf(text, sizeof text, "  axis %c (LPS mm per voxel) %.4f %.4f %.4f\n", "ijk"[a],
                  g.axes[a][0], g.axes[a][1], g.axes[a][2]);
    out << text;
  }
  for (const auto& w : file.warnings) out << "  warning: " << w << "\n";
  if (!listed) {
    out << (label_values ? "  more than 1000 distinct values: grey values, not labels\n"
                         : "  grey values (not a label map)\n");
    return kExitOk;
  }
  out << rows.size() << " label(s):\n";
  for (const LabelRow& row : rows) {
    std::snprintf(
        text, sizeof text,
        "  %6d  %-24s %10llu voxels %10.3f mL  box LPS mm [%.1f %.1f %.1f]..[%.1f %.1f %.1f]\n",
        row.label, row.name.c_str(), static_cast<unsigned long long>(row.extent.voxels),
        row.volume_ml, row.box_min[0], row.box_min[1], row.box_min[2], row.box_max[0],
        row.box_max[1], row.box_max[2]);
    out << text;
  }
  return kExitOk;
}

}  // namespace typemerge::app
