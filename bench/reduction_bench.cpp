// reduction_bench: what a reduction costs and keeps, in one run. Type merging at bounds in
// millimetres (--max-error) and at triangle targets (--reduce-to), against marching cubes'
// surface on the same grid.
//
//   reduction_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]
//                   [--epsilons 0.5,1,2] [--blocks 8,16,32] [--targets 0.25,0.1]
//                   [--spacing resample] [--threads 1] [--vtk /usr/bin/python3] [--baselines 0]
//
// --targets: shares of marching cubes' triangles; per share N, on one thread, extraction +
// reduction: tm --reduce-to N (extract_type_merged_to_count, cap 5 finest steps), OpenMesh's
// quadric decimater and meshoptimizer's simplifier on marching cubes' surface, and with --vtk
// (bench/vtk_reduce.py, python3-vtk9) flying edges + vtkQuadricDecimation and + vtkDecimatePro
// (topology preserved: the count it reaches); --baselines 0 leaves the two decimators out;
// Per bound, after the merge alone: what --max-error gives (extract_type_merged_within, the
// merge and its locally limited collapses); --exhaust 1 adds the merge collapsed as far as
// the bound allows. Each is measured against its own unreduced surface (tm and the
// decimators against marching cubes', VTK's against flying edges').
//
// Prints, per iso × bound × block size: one-thread extraction time, triangles and their share
// of marching cubes', the two-sided Hausdorff and mean distances to marching cubes' surface in
// mm (sampled at every vertex and centroid and at 1 point per mm² of both surfaces:
// core::area_samples, as --report measures), crossing triangle pairs (exact), whether the
// surface is closed and manifold with marching cubes' Euler characteristic and components, and
// caps (> 170°) and needles (< 1°) beside marching cubes'.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>
#include <map>
#include <vector>

#include <unistd.h>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/bounded_reduction.h"
#include "core/type_merging.h"
#include "io/nrrd_writer.h"
#include "io/stl_writer.h"
#include "mesh/decimation.h"
#include <meshoptimizer.h>
#include "default_series.h"
#include "list_argument.h"
#include "synthetic_volume.h"

namespace {

using namespace typemerge;
using Clock = std::chrono::steady_clock;

struct Quality {
  std::size_t triangles = 0;
  double hausdorff = 0;
  double mean = 0;
  std::size_t crossings = 0;
  bool valid = false;
  core::ExtremeAngles extremes;
};

// `mesh` in patient mm against `mc` (also in mm).
Quality measure(const core::TriangleMesh& mesh, const core::TriangleMesh& mc,
                const core::MeshCheck& mc_check, unsigned threads) {
  Quality q;
  q.triangles = mesh.triangles.size();
  const auto d = core::area_sampled_distance(mc, mesh, 1.0, threads);
  q.hausdorff = d.hausdorff();
  q.mean = d.mean();
  q.crossings = core::find_self_intersections(mesh, 1000).pairs.size();
  const core::MeshCheck check = core::check_mesh(mesh, threads);
  q.valid = check.closed_manifold() &&
            check.euler_characteristic == mc_check.euler_characteristic &&
            check.components == mc_check.components;
  q.extremes = core::count_extreme_angles(mesh);
  return q;
}

void print(const char* what, double ms, const Quality& q, std::size_t mc_triangles) {
  std::printf("  %-22s %9.1f ms %9zu tri %6.2f %%  Hausdorff %6.3f mm  mean %6.4f mm  "
              "crossings %zu  %s  caps %zu needles %zu\n",
              what, ms, q.triangles, 100.0 * double(q.triangles) / double(mc_triangles),
              q.hausdorff, q.mean, q.crossings, q.valid ? "closed, same topology" : "DEFECTS",
              q.extremes.above_170, q.extremes.below_1);
}

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// meshoptimizer's simplifier as its users call it: to a count, no error limit, then compacted.
core::TriangleMesh meshopt_simplified(const core::TriangleMesh& mesh, std::size_t target) {
  std::vector<unsigned> indices;
  for (const auto& t : mesh.triangles) indices.insert(indices.end(), t.begin(), t.end());
  std::vector<unsigned> out(indices.size());
  float error = 0;
  const std::size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(),
                                         &mesh.positions[0][0], mesh.positions.size(),
                                         sizeof(float) * 3, 3 * target, 1.0f, 0, &error);
  core::TriangleMesh result;
  std::vector<std::uint32_t> id(mesh.positions.size(), std::numeric_limits<std::uint32_t>::max());
  for (std::size_t i = 0; i + 2 < n; i += 3) {
    std::array<std::uint32_t, 3> t{};
    for (int k = 0; k < 3; ++k) {
      const unsigned v = out[i + static_cast<std::size_t>(k)];
      if (id[v] == std::numeric_limits<std::uint32_t>::max()) {
        id[v] = static_cast<std::uint32_t>(result.positions.size());
        result.positions.push_back(mesh.positions[v]);
      }
      t[static_cast<std::size_t>(k)] = id[v];
    }
    result.triangles.push_back(t);
  }
  return result;
}

int usage() {
  std::fprintf(stderr,
               "usage: reduction_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]\n"
               "         [--epsilons 0.5,1,2] [--blocks 8,16,32] [--spacing resample]\n"
               "         [--targets 0.25,0.1] [--baselines 1] [--exhaust 0] [--threads 1] [--vtk PYTHON]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each row as it is measured, also into a file
  std::string series_dir, synthetic, iso_list = "300,-500", epsilons = "0.5,1,2",
                                     blocks = "8,16,32", spacing, targets, vtk_python;
  unsigned threads = 1;
  bool baselines = true;  // OpenMesh and meshoptimizer beside tm at each target
  bool exhaust = false;   // each bound's merge also collapsed as far as the bound allows
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--series") series_dir = value;
    else if (key == "--synthetic") synthetic = value;
    else if (key == "--iso") iso_list = value;
    else if (key == "--epsilons") epsilons = value;
    else if (key == "--blocks") blocks = value;
    else if (key == "--spacing") spacing = value;
    else if (key == "--threads") threads = static_cast<unsigned>(std::stoul(value));
    else if (key == "--targets") targets = value;
    else if (key == "--vtk") vtk_python = value;
    else if (key == "--baselines") baselines = value != "0";
    else if (key == "--exhaust") exhaust = value != "0";
    else return usage();
  }
  if (series_dir.empty() == synthetic.empty()) return usage();
  core::Volume volume;
  if (!synthetic.empty()) {
    long nx = 0, ny = 0, nz = 0;
    if (std::sscanf(synthetic.c_str(), "%ldx%ldx%ld", &nx, &ny, &nz) != 3) return usage();
    volume = bench::synthetic_volume(nx, ny, nz);
  } else {
    auto loaded = bench::load_default_series(series_dir, spacing == "resample");
    if (!loaded) return 1;
    volume = std::move(*loaded);
  }
  const core::IndexToPatient& geometry = volume.geometry();
  std::printf("volume %lld x %lld x %lld, spacing %.3f x %.3f x %.3f mm\n",
              static_cast<long long>(volume.size().nx), static_cast<long long>(volume.size().ny),
              static_cast<long long>(volume.size().nz), geometry.spacing(0), geometry.spacing(1),
              geometry.spacing(2));
  core::ExtractOptions extract;
  extract.threads = 1;
  extract.vertex_normals = false;
  for (const std::string& iso_text : bench::split(iso_list)) {
    const float iso = std::stof(iso_text);
    auto start = Clock::now();
    core::TriangleMesh mc = core::extract_isosurface(volume, iso, extract);
    const double mc_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    core::to_patient(mc, geometry);
    const core::MeshCheck mc_check = core::check_mesh(mc, threads);
    std::printf("iso %g: mc %zu triangles in %.1f ms, caps %zu needles %zu\n", double(iso),
                mc.triangles.size(), mc_ms, core::count_extreme_angles(mc).above_170,
                core::count_extreme_angles(mc).below_1);
    {
      core::MergeOptions options;
      start = Clock::now();
      core::TriangleMesh tm = core::extract_type_merged(volume, iso, extract, options);
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      core::to_patient(tm, geometry);
      print("tm default (0.5 vox)", ms, measure(tm, mc, mc_check, threads), mc.triangles.size());
    }
    for (const std::string& epsilon_text : bench::split(epsilons)) {
      for (const std::string& block_text : bench::split(blocks)) {
        core::MergeOptions options;
        options.epsilon_mm = std::stod(epsilon_text);
        options.block_cubes = static_cast<unsigned>(std::stoul(block_text));
        start = Clock::now();
        core::TriangleMesh tm = core::extract_type_merged(volume, iso, extract, options);
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        core::to_patient(tm, geometry);
        const std::string what = "tm " + epsilon_text + " mm, B " + block_text;
        print(what.c_str(), ms, measure(tm, mc, mc_check, threads), mc.triangles.size());
        {
          // What --max-error gives: the merge, then collapses within the bound while each stays
          // locally within kLocalErrorShare of it.
          start = Clock::now();
          core::ReductionResult within = core::extract_type_merged_within(
              volume, iso, extract, options, options.epsilon_mm);
          const double within_ms = ms_since(start);
          core::to_patient(within.mesh, geometry);
          const std::string local = what + " --max-error";
          print(local.c_str(), within_ms, measure(within.mesh, mc, mc_check, threads),
                mc.triangles.size());
        }
        if (!exhaust) continue;
        // The merge, then bounded collapses as far as the bound allows.
        start = Clock::now();
        core::TriangleMesh reduced = core::extract_type_merged(volume, iso, extract, options);
        core::collapse_to_count(volume, iso, extract, reduced, 0, options.epsilon_mm);
        const double reduced_ms = ms_since(start);
        core::to_patient(reduced, geometry);
        const std::string with = what + " + collapses";
        print(with.c_str(), reduced_ms, measure(reduced, mc, mc_check, threads),
              mc.triangles.size());
      }
    }
    if (targets.empty()) continue;
    const double finest = std::min({geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)});
    std::vector<std::size_t> counts;
    for (const std::string& share : bench::split(targets)) {
      counts.push_back(static_cast<std::size_t>(std::stod(share) * double(mc.triangles.size())));
    }
    for (const std::size_t n : counts) {
      std::printf(" target %zu triangles (%.0f %% of mc)\n", n,
                  100.0 * double(n) / double(mc.triangles.size()));
      start = Clock::now();
      core::ReductionResult r = core::extract_type_merged_to_count(
          volume, iso, extract, {}, n, core::kReductionCapSteps * finest);
      double ms = ms_since(start);
      core::to_patient(r.mesh, geometry);
      char what[96];
      std::snprintf(what, sizeof what, "tm --reduce-to (%s, %.2f mm, %zu tries)",
                    r.target_met ? "met" : "NOT met", r.bound_mm, r.tries);
      print(what, ms, measure(r.mesh, mc, mc_check, threads), mc.triangles.size());
      if (r.collapse.collapses > 0 || r.collapse.held_reference_triangles > 0) {
        std::printf("    second stage: %zu collapses; refused: %zu topology, %zu shape, %zu distance, "
                    "%zu crossing; %zu mc triangles held\n",
                    r.collapse.collapses, r.collapse.refused_topology, r.collapse.refused_shape,
                    r.collapse.refused_distance, r.collapse.refused_crossing,
                    r.collapse.held_reference_triangles);
      }
      if (!baselines) continue;

      core::TriangleMesh openmesh = mc;
      start = Clock::now();
      mesh::DecimationOptions decimation;
      decimation.target_triangles = n;
      decimation.max_error = std::numeric_limits<double>::infinity();
      mesh::decimate_mesh(openmesh, decimation);
      print("mc + OpenMesh quadric", mc_ms + ms_since(start),
            measure(openmesh, mc, mc_check, threads), mc.triangles.size());

      start = Clock::now();
      const core::TriangleMesh simplified = meshopt_simplified(mc, n);
      print("mc + meshoptimizer", mc_ms + ms_since(start),
            measure(simplified, mc, mc_check, threads), mc.triangles.size());
    }
    if (vtk_python.empty()) continue;
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / ("reduction_bench_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const bool integral = volume.holds_int16() ||
                          std::all_of(volume.samples().begin(), volume.samples().end(),
                                      [](float v) {
                                        return v == std::floor(v) && v >= -32768.0f &&
                                               v <= 32767.0f;
                                      });
    io::write_nrrd(volume, dir / "volume.nrrd",
                   integral ? io::NrrdSampleType::int16 : io::NrrdSampleType::float32);
    std::string target_list;
    for (const std::size_t n : counts) target_list += (target_list.empty() ? "" : ",") + std::to_string(n);
    const std::string command = vtk_python + " " TYPEMERGE_BENCH_SOURCE_DIR "/vtk_reduce.py " +
                                (dir / "volume.nrrd").string() + " " + dir.string() + " --iso " +
                                iso_text + " --targets " + target_list;
    FILE* pipe = ::popen(command.c_str(), "r");
    std::map<std::string, double> seconds;
    char name[64];
    double s = 0;
    std::size_t count = 0;
    while (pipe != nullptr && std::fscanf(pipe, "%63s %lf %zu", name, &s, &count) == 3) seconds[name] = s;
    if (pipe == nullptr || ::pclose(pipe) != 0 || seconds.count("fe") == 0) {
      std::printf("  (vtk_reduce.py failed)\n");
      continue;
    }
    core::TriangleMesh fe = io::read_stl(dir / "fe.stl");
    core::to_patient(fe, geometry);
    const core::MeshCheck fe_check = core::check_mesh(fe, threads);
    print("VTK flying edges", 1000 * seconds["fe"], measure(fe, fe, fe_check, threads),
          mc.triangles.size());
    for (const std::size_t n : counts) {
      for (const char* route : {"quadric", "pro"}) {
        const std::string key = std::string(route) + "-" + std::to_string(n);
        core::TriangleMesh reduced = io::read_stl(dir / (key + ".stl"));
        core::to_patient(reduced, geometry);
        const std::string what = std::string("FE + vtk") +
                                 (route == std::string("quadric") ? "QuadricDecimation"
                                                                  : "DecimatePro");
        print(what.c_str(), 1000 * seconds[key], measure(reduced, fe, fe_check, threads),
              mc.triangles.size());
      }
    }
    fs::remove_all(dir);
  }
  return 0;
}
