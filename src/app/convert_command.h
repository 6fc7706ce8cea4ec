// `typemerge convert DIR (--preset A[,B…] | --iso HU | --window LO,HI) -o OUT`: the main job.
// Loads the series once, optionally preprocesses it, and for each requested tissue extracts,
// finishes and writes a binary STL (LPS mm) — or all of them as the coloured parts of one 3MF
// package — with an optional PNG preview and a JSON report.
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "app/input_options.h"
#include "app/memory_budget.h"
#include "app/surface_pipeline.h"

namespace typemerge::app {

struct ConvertOptions {
  InputOptions input;
  std::string series_id;
  std::string output;
  std::vector<std::string> presets;
  std::string iso;  // an iso value in the volume's units, "auto" (Otsu), or empty: not given
  std::vector<double> window;  // lo, hi
  bool open_borders = false;
  std::string algorithm = "tm";
  std::string finish = "default";  // default | none
  FinishOptions finish_options;
  std::optional<double> min_component_mm3;
  bool fill_cavities = false;
  bool preview = false;
  std::string report;
  bool report_distances = true;  // false: the report without the sampled distances (batch's)
  std::string denoise = "none";  // none | gaussian | median | bilateral
  double voxel_size_mm = 0;      // > 0: resample to isotropic voxels of this size
  bool crop_to_tissue = false;
  std::vector<double> crop_box_mm;  // x0,y0,z0,x1,y1,z1 in LPS mm
  bool remove_table = false;  // default on with presets
  bool keep_table = false;
  bool ascii_stl = false;
  unsigned threads = 0;
  std::string max_memory;  // e.g. "8G": refuse larger series up front, bound the address space
  std::string space = "lps";  // lps | ras
  bool center = false;
  bool show_descriptions = false;  // put the free-text SeriesDescription in the report
  bool check_intersections = false;  // count crossing triangle pairs of each output (CGAL)
  double hollow_mm = 0;  // > 0: hollow each surface to a shell of this wall thickness
  std::string removed_decimator;  // --decimator, refused with a message naming its replacement
  // Label mode (app/label_mode.h): "all" or "N[,N...]"; a label table; the mask's Gaussian sigma.
  std::string labels;
  std::string label_names;
  std::optional<double> label_smoothing_mm;
};

void add_convert_command(CLI::App& app, ConvertOptions& options);
// What to extract and how (presets, algorithm, preprocessing, finishing, output format): the
// options `batch` shares with `convert` and passes on to it.
void add_surface_options(CLI::App& command, ConvertOptions& options);
// The surfaces the options ask for; throws CommandError (usage) when they ask for none or for an
// unknown preset.
std::vector<SurfaceSpec> surface_specs(const ConvertOptions& options);
// What the options make a conversion hold, for conversion_memory_estimate (app/memory_budget.h).
ConversionShape conversion_shape(const ConvertOptions& options);
int run_convert(const ConvertOptions& options, std::ostream& log);

}  // namespace typemerge::app
