// pipeline_bench: the whole `typemerge convert` pipeline, stage by stage, with time, CPU time,
// throughput, triangles and peak memory of each stage.
//
//   pipeline_bench (--series DIR | --synthetic NXxNYxNZ [--as-dicom]) [--repeat-z K]
//                  [--preset bone,skin | --iso 300,-500] [--threads 1,2] [--repeat 3]
//                  [--out-dir /tmp] [--write-nrrd FILE] [--vtk] [--no-convert]
//                  [--typemerge build/src/app/typemerge] [--memory-only]
//                  [--convert-extra "--denoise gaussian"]
//
// --memory-only prints only the memory figure of `typemerge convert` (tm) per surface and
// thread count: its peak RSS as its own process, less 24 bytes a triangle of its output, over
// the series' voxels (print_memory_figures); --convert-extra adds options to that convert
// (a filter, --voxel-size, --hollow: docs/benchmarks.md, "filters in slabs").
//
// --as-dicom writes the synthetic volume as a CT series (tools/ct_writer, explicit little
// endian, 12-bit stored values) into --out-dir/pipeline_bench_dicom_NXxNYxNZ and measures it
// as --series: the loader is then part of the figures and VTK reads the same folder.
//
// Stages, in the order `convert` runs them (src/app/convert_command.cpp, surface_pipeline.cpp):
//   load     scan the folder and decode the default series (DICOM → HU); for --synthetic the
//            volume is generated instead; --repeat-z K then stacks K copies of the slices
//            along z (in memory), to grow N without new data
//   table    preprocess::remove_outside_body, as convert does whenever a preset is given
//   mc       consistent marching cubes alone (a window preset first builds its window field);
//            a reference for flying edges, not part of convert's path nor of the stage sum
//   tm       core::extract_type_merged, what convert runs: marching cubes and type merging
//            piece by piece (extraction included)
//   check    convert's checks around extraction: the tissue test (window_cover), the
//            map to patient mm (to_patient) and core::check_mesh of the extracted surface
//   finish   the preset's finishing as make_surface does it (keep largest / remove small
//            components / fill cavities, each with its result's check, derived from the
//            check before it where the step allows); none for --iso
//   write    binary STL into --out-dir (atomic: the file is fsync'ed before the rename)
// and, for --series without --repeat-z, `convert` itself run in-process (app::run_convert,
// the CLI's code path with the same preset or iso and thread count) as the whole-pipeline
// rows: `convert mc` (--algorithm mc: everything but the merge) and `convert tm` (the
// default). Each is run once more as its own process (--typemerge, default the build's
// src/app/typemerge beside this bench) for its peak RSS: less the output mesh, over the voxel
// count, it is printed as bytes a voxel, what a conversion holds besides its result.
//
// For --series the loader's floor is printed too: the same files read whole from the page
// cache (`read bytes`), and parsed by DCMTK (`dcmtk parse`: DcmFileFormat::loadFile with the
// pixel data, no decoding), each on the same threads as the loader. What load takes above
// `dcmtk parse` is ours (headers, decoding to HU, the volume's pages).
//
// Per stage it prints the median over --repeat runs of wall time and CPU time (all threads,
// CLOCK_PROCESS_CPUTIME_ID), M cells/s for the stages that visit every cell, triangles in and
// out, the resident memory before the stage (after malloc_trim, so memory freed by earlier
// stages does not count), its peak during the stage (VmHWM, reset before each stage by writing
// 5 to /proc/self/clear_refs; where that is refused the peak since the start is printed and
// marked) and the increase, and the mesh (with mc's cube records) held after the stage. Each
// block names the load average it started at: figures taken on a busy machine say so.
//
// --vtk runs bench/vtk_pipeline.py on the same input: the DICOM folder (vtkDICOMImageReader)
// for --series, else the volume written as NRRD (to --write-nrrd or --out-dir). It needs
// Debian's python3-vtk9 and python3-numpy (--vtk-python, --vtk-script to override) and times VTK's read →
// vtkFlyingEdges3D → binary vtkSTLWriter per stage on the same samples; the ratios to ours are
// printed from that one run.
#include <dcmtk/dcmdata/dcfilefo.h>
#include <malloc.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "app/convert_command.h"
#include "app/presets.h"
#include "ct_writer/ct_writer.h"
#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/type_merging.h"
#include "core/window_field.h"
#include "dicom/series_loader.h"
#include "io/mesh_writers.h"
#include "io/nrrd_writer.h"
#include "mesh/components.h"
#include "mesh/validity.h"
#include "preprocess/body_mask.h"
#include "list_argument.h"
#include "synthetic_volume.h"

#ifndef TYPEMERGE_BENCH_SOURCE_DIR
#define TYPEMERGE_BENCH_SOURCE_DIR "bench"
#endif

namespace {

using namespace typemerge;
namespace fs = std::filesystem;

// ---- process figures (Linux /proc) ---------------------------------------------------------

long status_kib(const char* field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  const std::size_t length = std::char_traits<char>::length(field);
  while (std::getline(status, line)) {
    if (line.compare(0, length, field) == 0) return std::stol(line.substr(length));
  }
  return -1;
}
long current_rss_kib() { return status_kib("VmRSS:"); }
long peak_rss_kib() { return status_kib("VmHWM:"); }

// Resets VmHWM to the current RSS; false when the kernel refuses (then peaks are cumulative).
bool reset_peak_rss() {
  {
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5";
    clear.flush();
    if (!clear) return false;
  }
  return peak_rss_kib() <= current_rss_kib() + 64;
}

// The 1-minute load average: on a shared machine, a figure taken at a load above the core
// count (or a cpu/w below 1 for one thread) was measured while competing for the CPU.
std::string load_average() {
  std::ifstream file("/proc/loadavg");
  std::string one;
  file >> one;
  return one.empty() ? "?" : one;
}

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + double(t.tv_nsec) * 1e-9;
}

double mesh_mib(const core::TriangleMesh& mesh) {
  return double(mesh.positions.size() * 12 + mesh.normals.size() * 12 +
                mesh.triangles.size() * 12) /
         double(1 << 20);
}

// ---- one stage's figures ---------------------------------------------------------------------

struct StageFigures {
  std::string name;
  double wall_ms = 0;
  double cpu_ms = 0;
  double cells = 0;  // cells visited, for M cells/s; 0 = not meaningful
  std::size_t triangles_in = 0;
  std::size_t triangles_out = 0;
  long rss_before_kib = 0;
  long peak_kib = 0;
  double mesh_mib = 0;  // the mesh held after the stage
  bool reference_only = false;  // measured for comparison, not a step of convert
};

bool g_peak_resets = true;  // whether clear_refs worked (decided once in main)

// Runs `work` as one stage and returns its figures (triangles and cells are filled in by
// the caller, which knows them).
StageFigures measure(const std::string& name, const std::function<void()>& work) {
  StageFigures figures;
  figures.name = name;
  ::malloc_trim(0);  // return what earlier stages freed, so rss0 is what is really held
  if (g_peak_resets) reset_peak_rss();
  figures.rss_before_kib = current_rss_kib();
  const double cpu_start = cpu_seconds();
  const auto start = std::chrono::steady_clock::now();
  work();
  figures.wall_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  figures.cpu_ms = (cpu_seconds() - cpu_start) * 1e3;
  figures.peak_kib = peak_rss_kib();
  return figures;
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0 : values[values.size() / 2];
}

// Median wall and CPU time per stage over the runs; memory and counts from the run with the
// largest peak increase (they are the same in every run up to allocator noise).
std::vector<StageFigures> summarize(const std::vector<std::vector<StageFigures>>& runs) {
  std::vector<StageFigures> summary = runs.front();
  for (std::size_t s = 0; s < summary.size(); ++s) {
    std::vector<double> wall, cpu;
    for (const auto& run : runs) {
      wall.push_back(run[s].wall_ms);
      cpu.push_back(run[s].cpu_ms);
      if (run[s].peak_kib - run[s].rss_before_kib >
          summary[s].peak_kib - summary[s].rss_before_kib) {
        summary[s].peak_kib = run[s].peak_kib;
        summary[s].rss_before_kib = run[s].rss_before_kib;
      }
    }
    summary[s].wall_ms = median(wall);
    summary[s].cpu_ms = median(cpu);
  }
  return summary;
}

void print_header() {
  std::printf("  %-16s %9s %9s %5s %9s %11s %11s %9s %9s %9s %9s\n", "stage", "wall ms", "cpu ms",
              "cpu/w", "Mcells/s", "tri in", "tri out", "rss0 MiB", "peak MiB", "peak+MiB",
              "mesh MiB");
}

void print_row(const StageFigures& f) {
  char rate[16] = "-";
  if (f.cells > 0) std::snprintf(rate, sizeof rate, "%.1f", f.cells / f.wall_ms / 1e3);
  std::printf("  %-16s %9.1f %9.1f %5.2f %9s %11zu %11zu %9.1f %9.1f %9.1f %9.1f\n", f.name.c_str(),
              f.wall_ms, f.cpu_ms, f.wall_ms > 0 ? f.cpu_ms / f.wall_ms : 0.0, rate, f.triangles_in,
              f.triangles_out, double(f.rss_before_kib) / 1024, double(f.peak_kib) / 1024,
              double(f.peak_kib - f.rss_before_kib) / 1024, f.mesh_mib);
}

// ---- what to extract ----------------------------------------------------------------------

struct Surface {
  std::string name;  // preset name or "iso<value>"
  double lo = 0;
  std::optional<double> hi;
  bool preset = false;  // convert removes the table and finishes only for presets
  double min_component_mm3 = 0;
  bool fill_cavities = false;
  bool keep_largest = false;
};

using typemerge::bench::split;

// ---- the input volume ---------------------------------------------------------------------

struct Input {
  std::string series_dir;
  long nx = 0, ny = 0, nz = 0;  // synthetic size
  int repeat_z = 1;
};

// K copies of the slices along z; the geometry keeps its slice step, so the stack is longer.
core::Volume repeat_along_z(const core::Volume& volume, int copies) {
  const auto& size = volume.size();
  // The same storage (int16 or float) as the volume; every sample is copied.
  core::Volume stacked = core::Volume::uninitialized({size.nx, size.ny, size.nz * copies},
                                                     volume.geometry(), volume.sample_type());
  const auto block = static_cast<std::size_t>(size.voxels());
  auto copy = [&](const auto* from, auto* to) {
    for (int c = 0; c < copies; ++c) std::copy(from, from + block, to + block * std::size_t(c));
  };
  if (volume.holds_int16()) {
    copy(volume.int16_samples().data(), stacked.int16_samples().data());
  } else {
    copy(volume.samples().data(), stacked.samples().data());
  }
  return stacked;
}

core::Volume load_input(const Input& input) {
  core::Volume volume;
  if (!input.series_dir.empty()) {
    const auto scan = dicom::scan_folder(input.series_dir, {});
    if (!scan.default_series) throw std::runtime_error("no usable series in " + input.series_dir);
    volume = dicom::load_series(scan.series[*scan.default_series]).volume;
  } else {
    volume = bench::synthetic_volume(input.nx, input.ny, input.nz);
  }
  if (input.repeat_z > 1) volume = repeat_along_z(volume, input.repeat_z);
  return volume;
}

// The synthetic volume as a CT series in `directory` (kept: a folder that already holds
// exactly nz files from an earlier run is reused, since writing 1,200 slices takes a while).
// 0.7 mm pixels, 1 mm slices as in synthetic_volume; HU rounded to 12-bit stored values with
// intercept −1024, so the loaded volume equals the synthetic one up to that rounding.
void write_synthetic_series(const Input& input, const fs::path& directory) {
  if (fs::is_directory(directory)) {
    const auto files = std::distance(fs::directory_iterator(directory), fs::directory_iterator());
    if (files == input.nz) return;
    fs::remove_all(directory);
  }
  const core::Volume volume = bench::synthetic_volume(input.nx, input.ny, input.nz);
  ct_writer::SeriesLayout layout;
  layout.uid_seed = "pipeline_bench/" + directory.filename().string();
  layout.columns = static_cast<std::uint16_t>(input.nx);
  layout.rows = static_cast<std::uint16_t>(input.ny);
  layout.slices = static_cast<std::int32_t>(input.nz);
  layout.pixel_spacing = {volume.geometry().spacing(1), volume.geometry().spacing(0)};
  layout.slice_spacing = volume.geometry().spacing(2);
  layout.hu = [&volume](int i, int j, int k) { return double(volume.at(i, j, k)); };
  // Written beside and renamed, so an interrupted run leaves no folder that looks complete.
  const fs::path partial = directory.string() + ".partial";
  fs::remove_all(partial);
  const auto specs_all = ct_writer::make_axial_series(layout);
  ct_writer::write_series(specs_all, partial);
  fs::rename(partial, directory);
}

// The loader's floor on `series`: every file read whole (page cache → memory), then parsed by
// DCMTK with its pixel data, on `threads` threads like the loader. Best of `repeat`.
struct LoadFloor {
  double read_ms = 0;
  double parse_ms = 0;
  std::uintmax_t bytes = 0;
  std::size_t files = 0;
};

LoadFloor measure_load_floor(const std::string& series_dir, unsigned threads, int repeat) {
  const auto scan = dicom::scan_folder(series_dir, {});
  if (!scan.default_series) return {};
  std::vector<fs::path> files;
  for (const auto& slice : scan.series[*scan.default_series].slices) files.push_back(slice.path);
  std::sort(files.begin(), files.end());
  files.erase(std::unique(files.begin(), files.end()), files.end());
  LoadFloor floor;
  floor.files = files.size();
  for (const auto& f : files) floor.bytes += fs::file_size(f);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  auto best_of = [&](const std::function<void(const fs::path&)>& work) {
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < repeat; ++r) {
      const auto start = std::chrono::steady_clock::now();
      tbb::parallel_for(std::size_t{0}, files.size(), [&](std::size_t f) { work(files[f]); });
      best = std::min(best, std::chrono::duration<double, std::milli>(
                                std::chrono::steady_clock::now() - start)
                                .count());
    }
    return best;
  };
  std::atomic<std::uintmax_t> read_bytes{0};
  floor.read_ms = best_of([&read_bytes](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes(fs::file_size(path));
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    read_bytes += static_cast<std::uintmax_t>(in.gcount());
  });
  if (read_bytes != floor.bytes * std::uintmax_t(repeat)) {
    throw std::runtime_error("load floor: short read of the series' files");
  }
  // Every value loaded, the pixel data included (DCMTK otherwise leaves values above 4 KiB on
  // disk until first use).
  floor.parse_ms = best_of([](const fs::path& path) {
    DcmFileFormat file;
    if (file.loadFile(OFFilename(path.c_str())).good()) file.loadAllDataIntoMemory();
  });
  return floor;
}

// ---- one run of every stage -----------------------------------------------------------------

struct RunSettings {
  Input input;
  Surface surface;
  unsigned threads = 1;
  fs::path out_dir;
};

std::vector<StageFigures> run_stages(const RunSettings& settings, double& cells, double& voxels) {
  std::vector<StageFigures> stages;
  const Surface& surface = settings.surface;

  core::Volume volume;
  stages.push_back(measure("load", [&] { volume = load_input(settings.input); }));
  const auto& size = volume.size();
  cells = double(size.nx - 1) * double(size.ny - 1) * double(size.nz - 1);
  voxels = double(size.nx) * double(size.ny) * double(size.nz);
  stages.back().cells = cells;

  if (surface.preset) {
    stages.push_back(measure(
        "table", [&] { volume = preprocess::remove_outside_body(std::move(volume)).volume; }));
    stages.back().cells = cells;
  }

  core::ExtractOptions extract;  // convert's defaults: consistent, closed borders
  extract.threads = settings.threads;
  extract.vertex_normals = false;  // as make_surface: a conversion writes no vertex normals
  // A window preset meshes its window field (built inside both stages, as make_surface does).
  auto extract_from = [&](auto&& extract_surface) {
    if (surface.hi) {
      const core::Volume field = core::window_field(volume, static_cast<float>(surface.lo),
                                                    static_cast<float>(*surface.hi));
      return extract_surface(field, 0.0f);
    }
    return extract_surface(volume, static_cast<float>(surface.lo));
  };
  core::TriangleMesh mesh;
  stages.push_back(measure("mc", [&] {
    mesh = extract_from([&](const core::Volume& v, float iso) {
      return core::extract_isosurface(v, iso, extract);
    });
  }));
  stages.back().cells = cells;
  stages.back().triangles_out = mesh.triangles.size();
  stages.back().mesh_mib = mesh_mib(mesh);
  stages.back().reference_only = true;
  mesh = {};

  core::MergeOptions merge;  // what extract_type_merged runs
  merge.threads = settings.threads;
  core::MergeStats merge_stats;
  stages.push_back(measure("tm", [&] {
    mesh = extract_from([&](const core::Volume& v, float iso) {
      return core::extract_type_merged(v, iso, extract, merge, &merge_stats);
    });
  }));
  stages.back().cells = cells;
  stages.back().triangles_in = merge_stats.triangles_before;
  stages.back().triangles_out = mesh.triangles.size();
  stages.back().mesh_mib = mesh_mib(mesh);

  core::MeshCheck check;
  stages.push_back(measure("check", [&] {
    const float hi =
        surface.hi ? static_cast<float>(*surface.hi) : std::numeric_limits<float>::infinity();
    if (core::window_cover(volume, static_cast<float>(surface.lo), hi) !=
        core::WindowCover::some) {
      throw std::runtime_error("no surface: no voxel (or every voxel) inside the range");
    }
    core::to_patient(mesh, volume.geometry());
    check = core::check_mesh(mesh, settings.threads);
  }));
  stages.back().triangles_in = stages.back().triangles_out = mesh.triangles.size();
  stages.back().mesh_mib = mesh_mib(mesh);

  volume = {};  // convert keeps the volume to the end; here it would only blur the figures
  if (surface.preset) {
    const std::size_t before = mesh.triangles.size();
    stages.push_back(measure("finish", [&] {
      // Each step derives its check from the one before when it can, as make_surface does.
      if (surface.keep_largest) {
        check = mesh::keep_largest_component(mesh, surface.fill_cavities ? mesh::Cavities::fill
                                                                         : mesh::Cavities::keep,
                                             &check, settings.threads)
                    .validity.check;
      }
      if (surface.min_component_mm3 > 0) {
        check = mesh::remove_small_components(mesh, surface.min_component_mm3, &check,
                                              settings.threads)
                    .validity.check;
      }
      if (surface.fill_cavities && !surface.keep_largest) {
        check = mesh::fill_cavities(mesh, &check, settings.threads).validity.check;
      }
      if (!check.closed_manifold()) mesh::check_validity(mesh);
    }));
    stages.back().triangles_in = before;
    stages.back().triangles_out = mesh.triangles.size();
    stages.back().mesh_mib = mesh_mib(mesh);
  }

  const fs::path stl = settings.out_dir / ("pipeline_bench_" + surface.name + ".stl");
  stages.push_back(measure("write", [&] {
    io::write_mesh(mesh, stl, io::MeshFormat::binary_stl, "typemerge pipeline_bench SPACE=LPS");
  }));
  stages.back().triangles_in = stages.back().triangles_out = mesh.triangles.size();
  stages.back().mesh_mib = mesh_mib(mesh);

  StageFigures total;
  total.name = "sum of stages";
  for (const auto& s : stages) {
    if (s.reference_only) continue;
    total.wall_ms += s.wall_ms;
    total.cpu_ms += s.cpu_ms;
    total.peak_kib = std::max(total.peak_kib, s.peak_kib);
  }
  total.triangles_out = mesh.triangles.size();
  total.rss_before_kib = stages.front().rss_before_kib;
  stages.push_back(total);
  return stages;
}

// `typemerge convert DIR (--preset NAME | --iso HU) -o OUT --threads T`, in-process.
StageFigures run_convert_once(const RunSettings& settings, const std::string& algorithm) {
  app::ConvertOptions options;
  options.algorithm = algorithm;
  options.input.input = settings.input.series_dir;
  if (settings.surface.preset)
    options.presets = {settings.surface.name};
  else
    options.iso = std::to_string(settings.surface.lo);  // convert parses it as --iso
  options.output =
      (settings.out_dir / ("pipeline_bench_convert_" + settings.surface.name + ".stl")).string();
  options.threads = settings.threads;
  std::ostringstream log;
  StageFigures figures = measure("convert " + algorithm, [&] { app::run_convert(options, log); });
  figures.triangles_out = (fs::file_size(options.output) - 84) / 50;  // binary STL size
  return figures;
}

// Peak RSS (KiB) of `typemerge convert` run as its own process with the same input, surface,
// algorithm and threads: the whole program's peak, as a user's `time -v` shows it. Through
// /usr/bin/time (Debian's `time`) because the kernel's figure for a child we fork or spawn
// ourselves starts at our own peak (exec records the old address space's peak as the child's),
// while time's child is forked from a small process. -1 if it could not run.
long convert_process_peak_kib(const std::string& typemerge, const RunSettings& settings,
                              const std::string& algorithm, const std::string& extra = "") {
  const fs::path out =
      settings.out_dir / ("pipeline_bench_process_" + settings.surface.name + ".stl");
  const fs::path figure = settings.out_dir / "pipeline_bench_process_peak.txt";
  std::string command = "/usr/bin/time -f %M -o '" + figure.string() + "' '" + typemerge +
                        "' convert '" + settings.input.series_dir + "'";
  command += settings.surface.preset ? " --preset " + settings.surface.name
                                     : " --iso " + std::to_string(settings.surface.lo);
  command += " --algorithm " + algorithm + " --threads " + std::to_string(settings.threads);
  if (!extra.empty()) command += " " + extra;
  command += " -o '" + out.string() + "' > /dev/null 2>&1";
  if (std::system(command.c_str()) != 0) return -1;
  std::ifstream in(figure);
  long kib = -1;
  in >> kib;
  return in ? kib : -1;
}

// --memory-only: per surface and thread count, `typemerge convert` (tm, the default) as its
// own process: its peak RSS less 24 bytes a triangle of its output (the mesh as
// core::TriangleMesh holds it), over the series' voxels — what a conversion holds besides
// its result. Needs --series (or --as-dicom).
int print_memory_figures(const std::string& typemerge, const Input& input,
                         const std::vector<Surface>& surfaces, const std::string& thread_list,
                         const fs::path& out_dir, const std::string& convert_extra) {
  if (input.series_dir.empty()) {
    std::fprintf(stderr, "--memory-only needs --series or --as-dicom\n");
    return 2;
  }
  const auto scan = dicom::scan_folder(input.series_dir, {});
  if (!scan.default_series) throw std::runtime_error("no usable series in " + input.series_dir);
  const dicom::SeriesInfo& series = scan.series[*scan.default_series];
  const double voxels = double(series.columns) * double(series.rows) *
                        double(series.geometry.output_slices);
  std::printf("memory: %s, %.1f M voxels, %s\n", input.series_dir.c_str(), voxels / 1e6,
              typemerge.c_str());
  for (const Surface& surface : surfaces) {
    for (const std::string& threads : split(thread_list)) {
      const RunSettings settings{input, surface, static_cast<unsigned>(std::stoi(threads)),
                                 out_dir};
      const long peak_kib = convert_process_peak_kib(typemerge, settings, "tm", convert_extra);
      const fs::path stl = out_dir / ("pipeline_bench_process_" + surface.name + ".stl");
      if (peak_kib < 0 || !fs::exists(stl)) {
        std::printf("  %s: could not run %s under /usr/bin/time\n", surface.name.c_str(),
                    typemerge.c_str());
        continue;
      }
      const double triangles = double((fs::file_size(stl) - 84) / 50);  // binary STL
      const double peak = double(peak_kib) * 1024.0;
      const double mesh_bytes = 24.0 * triangles;
      std::printf("  convert --preset/--iso %s --threads %s%s%s: peak RSS %.1f MiB, %.0f triangles "
                  "(~%.1f MiB): %.2f bytes a voxel besides the mesh\n",
                  surface.name.c_str(), threads.c_str(), convert_extra.empty() ? "" : " ",
                  convert_extra.c_str(), peak / (1 << 20), triangles,
                  mesh_bytes / (1 << 20), (peak - mesh_bytes) / voxels);
      std::fflush(stdout);
    }
  }
  return 0;
}

// ---- the VTK companion --------------------------------------------------------------------

// Runs bench/vtk_pipeline.py and collects its "stage NAME WALL_MS CPU_MS TRIANGLES PEAK_MIB"
// lines (it prints its own table too, which is passed through).
std::map<std::string, StageFigures> run_vtk(const std::string& python, const std::string& script,
                                            const std::string& source, double iso, unsigned threads,
                                            int repeat, const fs::path& out_dir) {
  std::map<std::string, StageFigures> stages;
  char command[2048];
  std::snprintf(command, sizeof command,
                "%s %s %s --iso %g --threads %u --repeat %d --out-dir %s --machine", python.c_str(),
                script.c_str(), source.c_str(), iso, threads, repeat, out_dir.string().c_str());
  FILE* pipe = ::popen(command, "r");
  if (pipe == nullptr) return stages;
  char line[512];
  while (std::fgets(line, sizeof line, pipe) != nullptr) {
    char name[64];
    StageFigures f;
    double peak_mib = 0;
    if (std::sscanf(line, "stage %63s %lf %lf %zu %lf", name, &f.wall_ms, &f.cpu_ms,
                    &f.triangles_out, &peak_mib) == 5) {
      f.name = name;
      f.peak_kib = static_cast<long>(peak_mib * 1024);
      stages[name] = f;
    } else {
      std::printf("    vtk| %s", line);
    }
  }
  if (::pclose(pipe) != 0) std::printf("    (vtk_pipeline.py failed: %s)\n", command);
  return stages;
}

int usage() {
  std::fprintf(stderr,
               "usage: pipeline_bench (--series DIR | --synthetic NXxNYxNZ [--as-dicom])\n"
               "       [--repeat-z K]\n"
               "       [--preset bone,skin | --iso 300,-500] [--threads 1,2] [--repeat 3]\n"
               "       [--out-dir /tmp] [--write-nrrd FILE] [--vtk] [--no-convert]\n"
               "       [--vtk-python /usr/bin/python3] [--vtk-script bench/vtk_pipeline.py]\n"
               "       [--typemerge build/src/app/typemerge] [--memory-only]\n"
               "       [--convert-extra \"--denoise gaussian\"]\n");
  return 2;
}

int run(int argc, char** argv) {
  Input input;
  std::string presets, isos,
      thread_list = "1", nrrd_out, out_dir = "/tmp", vtk_python = "/usr/bin/python3",
      typemerge = (fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "src" /
                   "app" / "typemerge")
                      .string(),
      vtk_script = std::string(TYPEMERGE_BENCH_SOURCE_DIR) + "/vtk_pipeline.py",
      convert_extra;
  int repeat = 3;
  bool vtk = false, convert = true, as_dicom = false, memory_only = false;
  for (int a = 1; a < argc; ++a) {
    const std::string key = argv[a];
    if (key == "--vtk") {
      vtk = true;
      continue;
    }
    if (key == "--no-convert") {
      convert = false;
      continue;
    }
    if (key == "--as-dicom") {
      as_dicom = true;
      continue;
    }
    if (key == "--memory-only") {
      memory_only = true;
      continue;
    }
    if (a + 1 >= argc) return usage();
    const std::string value = argv[++a];
    if (key == "--series")
      input.series_dir = value;
    else if (key == "--synthetic") {
      if (std::sscanf(value.c_str(), "%ldx%ldx%ld", &input.nx, &input.ny, &input.nz) != 3) {
        return usage();
      }
    } else if (key == "--repeat-z")
      input.repeat_z = std::max(1, std::stoi(value));
    else if (key == "--preset")
      presets = value;
    else if (key == "--iso")
      isos = value;
    else if (key == "--threads")
      thread_list = value;
    else if (key == "--repeat")
      repeat = std::max(1, std::stoi(value));
    else if (key == "--out-dir")
      out_dir = value;
    else if (key == "--write-nrrd")
      nrrd_out = value;
    else if (key == "--vtk-python")
      vtk_python = value;
    else if (key == "--vtk-script")
      vtk_script = value;
    else if (key == "--convert-extra")
      convert_extra = value;
    else if (key == "--typemerge")
      typemerge = value;
    else
      return usage();
  }
  if (input.series_dir.empty() == (input.nx == 0)) return usage();
  if (as_dicom && input.nx == 0) return usage();
  if (as_dicom) {
    const fs::path directory = fs::path(out_dir) / ("pipeline_bench_dicom_" + std::to_string(input.nx) +
                                                   "x" + std::to_string(input.ny) + "x" +
                                                   std::to_string(input.nz));
    fs::create_directories(out_dir);
    write_synthetic_series(input, directory);
    std::printf("synthetic series written as DICOM to %s\n", directory.c_str());
    input.series_dir = directory.string();
    input.nx = input.ny = input.nz = 0;
  }
  if (presets.empty() && isos.empty()) presets = "bone";

  std::vector<Surface> surfaces;
  for (const std::string& name : split(presets)) {
    const auto preset = app::find_preset(name);
    if (!preset) {
      std::fprintf(stderr, "unknown preset '%s'\n", name.c_str());
      return 2;
    }
    Surface s{
        preset->name,          preset->lo,          std::nullopt, true, preset->min_component_mm3,
        preset->fill_cavities, preset->keep_largest};
    if (std::isfinite(preset->hi)) s.hi = preset->hi;
    surfaces.push_back(s);
  }
  for (const std::string& text : split(isos)) {
    surfaces.push_back({"iso" + text, std::stod(text), std::nullopt, false, 0, false, false});
  }

  fs::create_directories(out_dir);
  if (memory_only) {
    return print_memory_figures(typemerge, input, surfaces, thread_list, out_dir, convert_extra);
  }
  g_peak_resets = reset_peak_rss();
  const std::string name = input.series_dir.empty()
                               ? "synthetic " + std::to_string(input.nx) + "x" +
                                     std::to_string(input.ny) + "x" + std::to_string(input.nz)
                               : input.series_dir;
  std::printf("pipeline_bench: %s%s, repeat %d (median), out-dir %s\n", name.c_str(),
              input.repeat_z > 1 ? (", slices x" + std::to_string(input.repeat_z)).c_str() : "",
              repeat, out_dir.c_str());
  std::printf("peak memory: %s\n", g_peak_resets
                                       ? "VmHWM reset before each stage (/proc/self/clear_refs)"
                                       : "clear_refs refused: peak is since process start");

  // What VTK reads: the DICOM folder itself, or (synthetic, --repeat-z) the volume as loaded,
  // before table removal, written once as NRRD.
  const bool vtk_reads_dicom = !input.series_dir.empty() && input.repeat_z == 1;
  if (vtk && !vtk_reads_dicom && nrrd_out.empty())
    nrrd_out = (fs::path(out_dir) / "pipeline_bench.nrrd").string();
  if (!nrrd_out.empty()) {
    io::write_nrrd(load_input(input), nrrd_out, io::NrrdSampleType::float32);
    std::printf("volume written to %s\n", nrrd_out.c_str());
  }

  const auto thread_texts = split(thread_list);
  for (std::size_t surface_index = 0; surface_index < surfaces.size(); ++surface_index) {
    const Surface& surface = surfaces[surface_index];
    for (std::size_t thread_index = 0; thread_index < thread_texts.size(); ++thread_index) {
      const std::string& thread_text = thread_texts[thread_index];
      RunSettings settings{input, surface, static_cast<unsigned>(std::stoi(thread_text)), out_dir};
      std::vector<std::vector<StageFigures>> runs;
      double cells = 0, voxels = 0;
      for (int r = 0; r < repeat; ++r) runs.push_back(run_stages(settings, cells, voxels));
      std::vector<StageFigures> summary = summarize(runs);

      // convert mc: everything but the merge; convert tm: the default.
      std::vector<StageFigures> wholes;
      if (convert && !input.series_dir.empty() && input.repeat_z == 1) {
        for (const char* algorithm : {"mc", "tm"}) {
          std::vector<std::vector<StageFigures>> convert_runs;
          for (int r = 0; r < repeat; ++r) {
            convert_runs.push_back({run_convert_once(settings, algorithm)});
          }
          wholes.push_back(summarize(convert_runs).front());
        }
      }

      std::printf("\n%s (%s %g HU), %s thread(s), %.1f M cells (load average %s):\n",
                  surface.name.c_str(), surface.preset ? "preset, lo" : "iso", surface.lo,
                  thread_text.c_str(), cells / 1e6, load_average().c_str());
      print_header();
      for (const auto& f : summary) print_row(f);
      for (const auto& whole : wholes) print_row(whole);
      for (const auto& whole : wholes) {
        // The output mesh as core::TriangleMesh holds it: 12 bytes of indices a triangle and
        // 24 of position and normal a vertex, with about half as many vertices as triangles.
        const double mesh_bytes = 24.0 * double(whole.triangles_out);
        const std::string algorithm = whole.name.substr(whole.name.find(' ') + 1);
        const long peak_kib = convert_process_peak_kib(typemerge, settings, algorithm);
        if (peak_kib < 0) {
          std::printf("  %s as its own process: could not run %s under /usr/bin/time\n",
                      whole.name.c_str(), typemerge.c_str());
          continue;
        }
        const double peak = double(peak_kib) * 1024.0;
        std::printf("  %s as its own process: peak RSS %.1f MiB, output mesh ~%.1f MiB: %.2f "
                    "bytes a voxel besides the mesh (%.1f M voxels)\n",
                    whole.name.c_str(), peak / (1 << 20), mesh_bytes / (1 << 20),
                    (peak - mesh_bytes) / voxels, voxels / 1e6);
      }
      if (!input.series_dir.empty() && surface_index == 0 && thread_index == 0) {
        const LoadFloor floor = measure_load_floor(input.series_dir, settings.threads, repeat);
        std::printf("  loader floor, %zu files, %.1f MiB, %u thread(s), best of %d: read bytes "
                    "%.1f ms (%.0f MiB/s), dcmtk parse %.1f ms; load %.1f ms, of which %.1f ms "
                    "above DCMTK's parse (headers, decoding to HU, the volume's pages)\n",
                    floor.files, double(floor.bytes) / (1 << 20), settings.threads, repeat,
                    floor.read_ms, double(floor.bytes) / (1 << 20) / (floor.read_ms / 1e3),
                    floor.parse_ms, summary.front().wall_ms,
                    summary.front().wall_ms - floor.parse_ms);
      }

      if (!vtk) continue;
      const std::string vtk_source =
          vtk_reads_dicom ? "--dicom " + input.series_dir : "--nrrd " + nrrd_out;
      const auto vtk_stages = run_vtk(vtk_python, vtk_script, vtk_source, surface.lo,
                                      settings.threads, repeat, out_dir);
      if (vtk_stages.count("read") == 0 || vtk_stages.count("flying_edges") == 0 ||
          vtk_stages.count("write") == 0) {
        continue;
      }
      auto stage = [&](const std::string& stage_name) {
        for (const auto& f : summary) {
          if (f.name == stage_name) return f.wall_ms;
        }
        return 0.0;
      };
      const double fe = vtk_stages.at("flying_edges").wall_ms;
      const double vtk_read = vtk_stages.at("read").wall_ms;
      const double vtk_write = vtk_stages.at("write").wall_ms;
      const double ours_after_load = summary.back().wall_ms - stage("load");
      std::printf("  %-16s %9.1f %9.1f %5.2f %9.1f %11s %11zu %9s %9.1f\n", "vtk read", vtk_read,
                  vtk_stages.at("read").cpu_ms, vtk_stages.at("read").cpu_ms / vtk_read,
                  cells / vtk_read / 1e3, "-", std::size_t{0}, "-",
                  double(vtk_stages.at("read").peak_kib) / 1024);
      std::printf("  %-16s %9.1f %9.1f %5.2f %9.1f %11s %11zu %9s %9.1f\n", "vtk flying_edges", fe,
                  vtk_stages.at("flying_edges").cpu_ms, vtk_stages.at("flying_edges").cpu_ms / fe,
                  cells / fe / 1e3, "-", vtk_stages.at("flying_edges").triangles_out, "-",
                  double(vtk_stages.at("flying_edges").peak_kib) / 1024);
      std::printf("  %-16s %9.1f %9.1f %5.2f %9s %11zu %11zu %9s %9.1f\n", "vtk write", vtk_write,
                  vtk_stages.at("write").cpu_ms, vtk_stages.at("write").cpu_ms / vtk_write, "-",
                  vtk_stages.at("flying_edges").triangles_out, vtk_stages.at("write").triangles_out,
                  "-", double(vtk_stages.at("write").peak_kib) / 1024);
      std::printf("  ratios (ours / VTK, wall, < 1 = ours faster):\n");
      std::printf("    mc / flying_edges                      %6.2f\n", stage("mc") / fe);
      std::printf("    tm (extract + merge) / flying_edges    %6.2f\n", stage("tm") / fe);
      std::printf(
          "    stages after load / (FE + write)       %6.2f   (ours %.0f ms incl. "
          "table, checks, finishing)\n",
          ours_after_load / (fe + vtk_write), ours_after_load);
      std::printf(
          "    sum of stages / (read + FE + write)    %6.2f   (our load decodes %s; "
          "VTK reads %s)\n",
          summary.back().wall_ms / (vtk_read + fe + vtk_write),
          input.series_dir.empty() ? "nothing (synthetic)" : "DICOM",
          vtk_reads_dicom ? "the DICOM folder" : "the NRRD");
      for (const auto& whole : wholes) {
        std::printf("    %-10s / (read + FE + write)       %6.2f\n", whole.name.c_str(),
                    whole.wall_ms / (vtk_read + fe + vtk_write));
      }
    }
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "pipeline_bench: %s\n", error.what());
    return 1;
  }
}
