// extract_bench: surface extraction speed and quality on a real series or a synthetic volume.
//
//   extract_bench --series DIR [--iso 300,-500]
//                 [--algorithms mc,classic,tm,classify]
//                 [--threads 1,2] [--repeat 5]
//   extract_bench --synthetic 512x512x300 [--write-nrrd vol.nrrd] ...
//   --slab-layers N: type merging's piece height (MergeOptions::slab_layers; default 32)
//   --spacing resample: accept a series with uneven slice steps as convert's --resample-spacing
//   --vertex-normals: mc and tm also compute gradient vertex normals (ExtractOptions::
//     vertex_normals). Off by default, as convert extracts and as --vtk runs flying edges
//     (ComputeNormalsOff); until 2026-12-04 this bench always computed them.
//
// Prints, per volume × iso × algorithm × threads: median wall time, cells/s, triangles,
// vertices, the peak resident memory added during extraction, and the validity of the surface
// (boundary, non-manifold and degenerate counts). For tm it then prints the triangle ratio to
// mc and the symmetric Hausdorff and mean distances between the two surfaces, in voxels and
// mm, vertex-sampled and sampled over both surfaces (every 0.25 voxel, in voxels;
// vertex samples alone miss the insides of merged polygons); for mc the ambiguity statistics of
// the paper's Table 4. For every surface: crossing triangle pairs in patient mm as convert writes them
// (exact, core/self_intersections.h) and the shares of triangles with an angle above 170° and
// below 1° (needles and slivers that slicers and FE tools dislike).
// `classify` is no extractor: one thread classifies every sample against the iso value and
// counts the cut x-edges — the first pass of flying edges and of ours, which any extractor
// must make, i.e. a floor for the time of any surface extraction (no triangles).
// The same volume can be written as NRRD for bench/vtk_extract.py, so that VTK's filters run on
// identical samples; --vtk does that itself (int16 samples where the volume is integral, as
// VTK would read a CT) and prints, per iso, mc and tm on one thread against
// vtkFlyingEdges3D on one thread, and tm's two-thread speed-up, all from this one run
// (the speed-up from one- and two-thread runs in alternation, the median of their pairs'
// ratios, whenever --threads lists 2, beside the host's own ratios on perfectly parallel work
// in a core's cache and streaming memory, in the same pairs: host_scaling.h); needs
// python3-vtk9 and python3-numpy; --vtk-python to choose the interpreter).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/type_merging.h"
#include "io/nrrd_writer.h"
#include "default_series.h"
#include "host_scaling.h"
#include "list_argument.h"
#include "synthetic_volume.h"

namespace {

using namespace typemerge;

// Peak RSS since the last reset, from /proc (Linux): writing "5" to clear_refs resets VmHWM.
void reset_peak_memory() { std::ofstream("/proc/self/clear_refs") << "5"; }
long peak_memory_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}
// Shares (%) of triangles whose largest angle exceeds 170° and whose smallest is under 1°.
struct AngleShares {
  double above_170 = 0;
  double below_1 = 0;
};
AngleShares angle_shares(const core::TriangleMesh& mesh) {
  const core::ExtremeAngles counts = core::count_extreme_angles(mesh);
  const double n = static_cast<double>(std::max<std::size_t>(1, mesh.triangles.size()));
  return {100.0 * static_cast<double>(counts.above_170) / n,
          100.0 * static_cast<double>(counts.below_1) / n};
}

long current_memory_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

using typemerge::bench::split;

// The `classify` floor: inside flags of every sample, then the cut x-edges counted (two plain
// loops the compiler vectorises; rows are not told apart, which changes the count by a few
// row ends and the time by nothing).
std::size_t classify_and_count_cuts(const core::Volume& volume, float iso,
                                    std::vector<std::uint8_t>& inside) {
  inside.resize(static_cast<std::size_t>(volume.size().voxels()));
  volume.visit([&](const auto* samples) {
    std::transform(samples, samples + inside.size(), inside.begin(),
                   [iso](float f) { return std::uint8_t{f >= iso}; });
  });
  std::size_t cuts = 0;
  for (std::size_t i = 0; i + 1 < inside.size(); ++i) cuts += inside[i] != inside[i + 1];
  return cuts;
}

// The median of the repeated runs' times (the upper one of an even count).
double median_ms(std::vector<double> times) {
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

int usage() {
  std::fprintf(stderr,
               "usage: extract_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]\n"
               "       [--algorithms mc,classic,tm,classify] [--threads 1,2] [--repeat 5]\n"
               "       [--vtk] [--vtk-python /usr/bin/python3] [--vertex-normals]\n"
               "       [--write-nrrd FILE] [--spacing refuse|resample] [--slab-layers N]\n"
               "       [--float]  (float samples even where int16 holds them)\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string vtk_python = "/usr/bin/python3";
  bool vtk = false;
  bool vertex_normals = false;
  bool float_samples = false;
  std::string series_dir, synthetic, nrrd_out, iso_list = "300,-500", algorithms = "mc,classic,tm",
              thread_list = "1", spacing = "refuse";
  int repeat = 5;
  unsigned slab_layers = core::MergeOptions{}.slab_layers;
  for (int a = 1; a < argc; ++a) {
    const std::string key = argv[a];
    if (key == "--vtk") {
      vtk = true;
      continue;
    }
    if (key == "--float") {
      float_samples = true;
      continue;
    }
    if (key == "--vertex-normals") {
      vertex_normals = true;
      continue;
    }
    if (a + 1 >= argc) return usage();
    const std::string value = argv[++a];
    if (key == "--series") series_dir = value;
    else if (key == "--synthetic") synthetic = value;
    else if (key == "--iso") iso_list = value;
    else if (key == "--algorithms") algorithms = value;
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--write-nrrd") nrrd_out = value;
    else if (key == "--vtk-python") vtk_python = value;
    else if (key == "--threads") thread_list = value;
    else if (key == "--spacing") spacing = value;
    else if (key == "--slab-layers") slab_layers = static_cast<unsigned>(std::stoul(value));
    else return usage();
  }
  if (series_dir.empty() == synthetic.empty()) return usage();
  if (spacing != "refuse" && spacing != "resample") return usage();

  core::Volume volume;
  std::string name;
  if (!series_dir.empty()) {
    auto loaded = bench::load_default_series(series_dir, spacing == "resample");
    if (!loaded) return 1;
    volume = std::move(*loaded);
    name = series_dir;
  } else {
    long nx = 0, ny = 0, nz = 0;
    if (std::sscanf(synthetic.c_str(), "%ldx%ldx%ld", &nx, &ny, &nz) != 3) return usage();
    volume = bench::synthetic_volume(nx, ny, nz);
    name = "synthetic " + synthetic;
  }
  if (float_samples) volume.to_float();
  if (vtk && nrrd_out.empty()) nrrd_out = "/tmp/extract_bench_vtk.nrrd";
  if (!nrrd_out.empty()) {
    // int16 where every sample is an integer in range (a CT as VTK would read it).
    const bool integral =
        volume.holds_int16() ||
        std::all_of(volume.samples().begin(), volume.samples().end(), [](float v) {
          return v == std::floor(v) && v >= -32768.0f && v <= 32767.0f;
        });
    io::write_nrrd(volume, nrrd_out,
                   integral ? io::NrrdSampleType::int16 : io::NrrdSampleType::float32);
  }
  // Per iso: one-thread mc and tm (ms), for the ratios to VTK.
  std::map<std::string, std::array<double, 2>> figures;
  std::map<std::string, double> scaling;  // tm: median of one thread / two threads, in pairs
  // The same for the host's perfectly parallel work: in a core's cache, streaming memory.
  std::map<std::string, std::array<double, 2>> host_scaling;
  const auto& size = volume.size();
  const double cells = double(size.nx - 1) * double(size.ny - 1) * double(size.nz - 1);
  std::printf("volume: %s, %lldx%lldx%lld (%.1f M cells, %.0f MiB of %s samples)\n",
              name.c_str(), static_cast<long long>(size.nx), static_cast<long long>(size.ny),
              static_cast<long long>(size.nz), cells / 1e6,
              double(volume.sample_bytes()) / (1 << 20), volume.holds_int16() ? "int16" : "float");
  std::printf("%-8s %-8s %3s %10s %10s %11s %10s %10s %9s %9s %9s\n", "iso", "algo", "thr", "ms",
              "Mcells/s", "triangles", "vertices", "peak+MiB", "boundary", "nonmanif", "degen");
  for (const std::string& iso_text : split(iso_list)) {
    const float iso = std::stof(iso_text);
    core::TriangleMesh reference;  // the mc surface of this iso, for tm's ratio and distances
    for (const std::string& algorithm : split(algorithms)) {
      if (algorithm == "classify") {
        std::vector<std::uint8_t> inside;
        std::vector<double> times;
        std::size_t cuts = 0;
        for (int r = 0; r < repeat; ++r) {
          const auto start = std::chrono::steady_clock::now();
          cuts = classify_and_count_cuts(volume, iso, inside);
          const auto end = std::chrono::steady_clock::now();
          times.push_back(std::chrono::duration<double, std::milli>(end - start).count());
        }
        const double median = median_ms(times);
        std::printf("%-8s %-8s %3s %10.1f %10.1f    (no surface: %zu cut x-edges)\n",
                    iso_text.c_str(), algorithm.c_str(), "1", median, cells / median / 1e3, cuts);
        continue;
      }
      for (const std::string& thread_text : split(thread_list)) {
        core::ExtractOptions options;
        options.threads = static_cast<unsigned>(std::stoi(thread_text));
        options.vertex_normals = vertex_normals;
        core::AmbiguityStats ambiguity;
        const bool merged = algorithm == "tm";
        if (algorithm == "classic") options.mode = core::ExtractOptions::Mode::classic;
        else if (algorithm == "mc") options.stats = &ambiguity;
        else if (!merged) return usage();
        core::MergeOptions merge;
        merge.slab_layers = slab_layers;
        merge.threads = options.threads;
        std::vector<double> times;
        core::TriangleMesh mesh;
        core::MergeStats merge_stats;
        long peak_added = 0;
        for (int r = 0; r < repeat; ++r) {
          mesh = {};
          ambiguity = {};
          merge_stats = {};
          const long before = current_memory_kib();
          reset_peak_memory();
          const auto start = std::chrono::steady_clock::now();
          mesh = merged ? core::extract_type_merged(volume, iso, options, merge, &merge_stats)
                        : core::extract_isosurface(volume, iso, options);
          const auto end = std::chrono::steady_clock::now();
          peak_added = std::max(peak_added, peak_memory_kib() - before);
          times.push_back(std::chrono::duration<double, std::milli>(end - start).count());
        }
        const double median = median_ms(times);
        if (thread_text == "1" && (algorithm == "mc" || merged)) {
          figures[iso_text][merged ? 1 : 0] = median;
        }
        if (thread_text == "2" && merged) {
          // Two threads against one, timed in alternation and taken pair by pair: the
          // medians above are minutes apart, and a host whose speed drifts in between moves
          // their ratio more than threads do.
          // The host's own two-thread ratios on perfectly parallel work, in a core's cache and
          // streaming memory, are taken in each pair as well (bench/host_scaling.h): tm's
          // ratio is read against them.
          static bench::HostProbe probe;
          std::vector<double> ratios;
          std::vector<double> cached;
          std::vector<double> streaming;
          for (int r = 0; r < repeat; ++r) {
            double pair_ms[2];
            for (unsigned t : {1u, 2u}) {
              core::ExtractOptions alone = options;
              alone.threads = t;
              core::MergeOptions merge_alone = merge;
              merge_alone.threads = t;
              mesh = {};
              const auto start = std::chrono::steady_clock::now();
              mesh = core::extract_type_merged(volume, iso, alone, merge_alone);
              pair_ms[t - 1] = std::chrono::duration<double, std::milli>(
                                   std::chrono::steady_clock::now() - start)
                                   .count();
            }
            ratios.push_back(pair_ms[0] / pair_ms[1]);
            cached.push_back(probe.cached_ms(1) / probe.cached_ms(2));
            streaming.push_back(probe.streaming_ms(1) / probe.streaming_ms(2));
          }
          scaling[iso_text] = median_ms(ratios);
          host_scaling[iso_text] = {median_ms(cached), median_ms(streaming)};
          const auto listed = [](const std::vector<double>& values) {
            std::string text;
            for (double value : values) {
              char item[16];
              std::snprintf(item, sizeof item, "%s%.2f", text.empty() ? "" : ", ", value);
              text += item;
            }
            return text;
          };
          std::printf("    tm one thread / two threads, %d alternating pairs: median %.2f (%s)\n",
                      repeat, scaling[iso_text], listed(ratios).c_str());
          std::printf("    the host in the same pairs, perfectly parallel work (host_scaling.h): "
                      "in cache %.2f (%s); streaming memory %.2f (%s)\n",
                      host_scaling[iso_text][0], listed(cached).c_str(),
                      host_scaling[iso_text][1], listed(streaming).c_str());
        }
        const core::MeshCheck check = core::check_mesh(mesh);
        std::printf("%-8s %-8s %3s %10.1f %10.1f %11zu %10zu %10.1f %9zu %9zu %9zu\n",
                    iso_text.c_str(), algorithm.c_str(), thread_text.c_str(), median,
                    cells / median / 1e3, mesh.triangles.size(), mesh.positions.size(),
                    double(peak_added) / 1024, check.boundary_edges,
                    check.non_manifold_edges + check.non_manifold_vertices,
                    check.degenerate_triangles);
        if (thread_text == split(thread_list).front()) {
          core::TriangleMesh written = mesh;
          core::to_patient(written, volume.geometry());
          const auto crossing_start = std::chrono::steady_clock::now();
          const std::size_t crossings = core::find_self_intersections(written).pairs.size();
          const double crossing_ms = std::chrono::duration<double, std::milli>(
                                         std::chrono::steady_clock::now() - crossing_start)
                                         .count();
          const AngleShares angles = angle_shares(written);
          std::printf("    crossing pairs %zu (counted in %.0f ms); angles > 170°: %.2f%%, "
                      "< 1°: %.2f%%\n",
                      crossings, crossing_ms, angles.above_170, angles.below_1);
        }
        if (algorithm == "mc" && thread_text == split(thread_list).front()) {
          reference = mesh;
          std::printf("    ambiguity (Table 4): %zu surface cubes; 1/2/3/6-face: %zu/%zu/%zu/%zu; "
                      "rate %.3f%%\n",
                      ambiguity.boundary_cubes, ambiguity.cubes_with_ambiguous_faces[1],
                      ambiguity.cubes_with_ambiguous_faces[2],
                      ambiguity.cubes_with_ambiguous_faces[3],
                      ambiguity.cubes_with_ambiguous_faces[6],
                      100.0 *
                          double(ambiguity.cubes_with_ambiguous_faces[1] +
                                 ambiguity.cubes_with_ambiguous_faces[2] +
                                 ambiguity.cubes_with_ambiguous_faces[3] +
                                 ambiguity.cubes_with_ambiguous_faces[6]) /
                          double(std::max<std::size_t>(1, ambiguity.boundary_cubes)));
        }
        if (merged && !reference.empty() && thread_text == split(thread_list).front()) {
          const core::MeshCheck mc_check = core::check_mesh(reference);
          const auto voxels = core::mesh_distance(reference, mesh);
          core::TriangleMesh reference_mm = reference, mesh_mm = mesh;
          core::to_patient(reference_mm, volume.geometry());
          core::to_patient(mesh_mm, volume.geometry());
          const auto mm = core::mesh_distance(reference_mm, mesh_mm);
          const auto sampled = core::surface_distance(reference, mesh, 0.25);
          std::printf("    tm/mc triangles %.1f%%; Hausdorff %.3f voxel (%.3f mm), mean %.4f voxel "
                      "(%.4f mm); Euler %lld vs %lld, components %zu vs %zu\n",
                      100.0 * double(mesh.triangles.size()) / double(reference.triangles.size()),
                      voxels.hausdorff(), mm.hausdorff(), voxels.mean(), mm.mean(),
                      static_cast<long long>(check.euler_characteristic),
                      static_cast<long long>(mc_check.euler_characteristic), check.components,
                      mc_check.components);
          std::printf("    sampled over both surfaces (every 0.25 voxel): Hausdorff %.3f voxel, "
                      "mean %.4f voxel\n",
                      sampled.hausdorff(), sampled.mean());
          std::fflush(stdout);
          const auto& f = merge_stats;
          std::printf(
              "    disks merged in blocks 2x1x1 or 2x2x1/2/4/8/16: %zu/%zu/%zu/%zu/%zu; "
              "blocks not merged: topology %zu facing %zu flatness %zu outline %zu "
              "separation %zu; split %zu, demoted %zu; face vertices thinned %zu (restored %zu) in "
              "%zu passes\n",
              f.blocks_merged[0], f.blocks_merged[1], f.blocks_merged[2], f.blocks_merged[3],
              f.blocks_merged[4], f.rejected_topology, f.rejected_facing, f.rejected_flatness,
              f.rejected_outline, f.rejected_separation, f.blocks_split, f.blocks_demoted,
              f.face_vertices_removed, f.face_vertices_restored, f.triangulation_passes);
          // The ceiling of a pre-test that rejects boxes before their components are built:
          // the share of step 1's test work spent on boxes that then failed.
          auto share = [](std::size_t part, std::size_t whole) {
            return whole == 0 ? 0.0 : 100.0 * double(part) / double(whole);
          };
          std::printf(
              "    step 1 work on boxes that failed (a pre-test's ceiling): %zu of %zu "
              "triangles tested (%.1f%%), %zu of %zu parts' loop vertices (%.1f%%)\n",
              f.tested_triangles_failed, f.tested_triangles,
              share(f.tested_triangles_failed, f.tested_triangles), f.tested_loop_vertices_failed,
              f.tested_loop_vertices,
              share(f.tested_loop_vertices_failed, f.tested_loop_vertices));
        }
      }
    }
  }
  if (vtk) {
    const std::string command = vtk_python + " " + TYPEMERGE_BENCH_SOURCE_DIR +
                                "/vtk_extract.py " + nrrd_out + " --iso=" + iso_list +
                                " --repeat " + std::to_string(repeat) + " --no-defects";
    std::printf("VTK, same samples, one thread (%s):\n", command.c_str());
    std::fflush(stdout);
    FILE* pipe = ::popen(command.c_str(), "r");
    std::map<double, double> flying_edges;  // iso → ms
    char line[512];
    while (pipe != nullptr && std::fgets(line, sizeof line, pipe) != nullptr) {
      std::printf("    vtk| %s", line);
      char filter[64];
      double iso = 0.0, ms = 0.0;
      if (std::sscanf(line, "%lf %63s %lf", &iso, filter, &ms) == 3 &&
          std::strcmp(filter, "flying_edges") == 0) {
        flying_edges[iso] = ms;
      }
    }
    if (pipe == nullptr || ::pclose(pipe) != 0) std::printf("    (vtk_extract.py failed)\n");
    std::printf("%-8s %10s %10s %10s %10s %10s %12s %16s\n", "iso", "FE ms", "mc ms", "tm ms",
                "mc/FE", "tm/FE", "tm 1thr/2thr", "host cache/mem");
    for (const auto& [iso_text, f] : figures) {
      const auto fe = flying_edges.find(std::stod(iso_text));
      if (fe == flying_edges.end()) continue;
      const auto pairs = scaling.find(iso_text);
      const auto host = host_scaling.find(iso_text);
      const std::array<double, 2> ceiling =
          host != host_scaling.end() ? host->second : std::array<double, 2>{0.0, 0.0};
      std::printf("%-8s %10.1f %10.1f %10.1f %10.2f %10.2f %12.2f %11.2f/%.2f\n",
                  iso_text.c_str(), fe->second, f[0], f[1], f[0] / fe->second, f[1] / fe->second,
                  pairs != scaling.end() ? pairs->second : 0.0, ceiling[0], ceiling[1]);
    }
  }
  return 0;
}
