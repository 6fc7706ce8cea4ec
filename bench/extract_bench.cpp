// extract_bench: surface extraction speed and quality on a real series or a synthetic volume.
//
//   extract_bench --series DIR [--iso 300,-500] [--algorithms mc,classic,tm] [--threads 1,2]
//                 [--repeat 5]
//   extract_bench --synthetic 512x512x300 [--write-nrrd vol.nrrd] ...
//
// Prints, per volume × iso × algorithm × threads: median wall time, cells/s, triangles,
// vertices, the peak resident memory added during extraction, and the validity of the surface
// (boundary, non-manifold and degenerate counts). For tm it then prints the triangle ratio to
// mc and the symmetric Hausdorff and mean distances between the two surfaces, in voxels and
// mm; for mc the ambiguity statistics of the paper's Table 4. The same volume can be written as
// NRRD for bench/vtk_extract.py, so that VTK's filters run on identical samples.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/type_merging.h"
#include "dicom/series_loader.h"
#include "io/nrrd_writer.h"

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
long current_memory_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

// A CT-like synthetic volume: a body ellipsoid of soft tissue with a fat layer, a bony shell
// and a few bone pieces, in air, with deterministic noise (σ ≈ 20 HU). 0.7 mm in-plane, 1 mm
// slices.
core::Volume synthetic_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz) {
  core::IndexToPatient geometry;
  geometry.axes = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 1.0}}};
  core::Volume volume({nx, ny, nz}, geometry);
  std::uint64_t state = 0x9E3779B97F4A7C15ull;
  auto noise = [&] {  // sum of 4 uniforms: cheap, deterministic, roughly normal
    double sum = 0;
    for (int n = 0; n < 4; ++n) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      sum += static_cast<double>(state >> 11) * (1.0 / 9007199254740992.0) - 0.5;
    }
    return sum * 20.0 / 0.577;
  };
  const double cx = double(nx) / 2, cy = double(ny) / 2, cz = double(nz) / 2;
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      float* row = volume.slice(k) + j * nx;
      for (std::int64_t i = 0; i < nx; ++i) {
        const double x = (double(i) - cx) / (0.42 * double(nx)), y = (double(j) - cy) / (0.36 * double(ny)),
                     z = (double(k) - cz) / (0.48 * double(nz));
        const double r = std::sqrt(x * x + y * y + 0.3 * z * z);
        double hu = -1000;
        if (r < 1.0) hu = r > 0.95 ? -90 : 40;                       // skin and fat
        if (r > 0.70 && r < 0.76) hu = 1100;                         // bony shell
        const double sx = x - 0.3 * std::sin(6 * z), sy = y + 0.2;   // a winding "spine"
        if (sx * sx + sy * sy < 0.01) hu = 600;
        for (int b = 0; b < 6; ++b) {                                // small bone pieces
          const double bx = x + 0.4 - 0.15 * b, by = y - 0.3, bz = z - 0.5 + 0.2 * b;
          if (bx * bx + by * by + bz * bz < 0.002) hu = 900;
        }
        row[i] = static_cast<float>(hu + noise());
      }
    }
  }
  return volume;
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  std::string part;
  while (std::getline(stream, part, ',')) parts.push_back(part);
  return parts;
}

int usage() {
  std::fprintf(stderr,
               "usage: extract_bench (--series DIR | --synthetic NXxNYxNZ) [--iso 300,-500]\n"
               "       [--algorithms mc,classic,tm] [--threads 1,2] [--repeat 5] [--write-nrrd FILE]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string series_dir, synthetic, nrrd_out, iso_list = "300,-500", algorithms = "mc,classic,tm",
              thread_list = "1";
  int repeat = 5;
  for (int a = 1; a + 1 < argc; a += 2) {
    const std::string key = argv[a], value = argv[a + 1];
    if (key == "--series") series_dir = value;
    else if (key == "--synthetic") synthetic = value;
    else if (key == "--iso") iso_list = value;
    else if (key == "--algorithms") algorithms = value;
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--write-nrrd") nrrd_out = value;
    else if (key == "--threads") thread_list = value;
    else return usage();
  }
  if (series_dir.empty() == synthetic.empty()) return usage();

  core::Volume volume;
  std::string name;
  if (!series_dir.empty()) {
    const auto scan = dicom::scan_folder(series_dir, {});
    if (!scan.default_series) {
      std::fprintf(stderr, "no usable series in %s\n", series_dir.c_str());
      return 1;
    }
    volume = dicom::load_series(scan.series[*scan.default_series]).volume;
    name = series_dir;
  } else {
    long nx = 0, ny = 0, nz = 0;
    if (std::sscanf(synthetic.c_str(), "%ldx%ldx%ld", &nx, &ny, &nz) != 3) return usage();
    volume = synthetic_volume(nx, ny, nz);
    name = "synthetic " + synthetic;
  }
  if (!nrrd_out.empty()) io::write_nrrd(volume, nrrd_out, io::NrrdSampleType::float32);
  const auto& size = volume.size();
  const double cells = double(size.nx - 1) * double(size.ny - 1) * double(size.nz - 1);
  std::printf("volume: %s, %lldx%lldx%lld (%.1f M cells, %.0f MiB of samples)\n", name.c_str(),
              static_cast<long long>(size.nx), static_cast<long long>(size.ny),
              static_cast<long long>(size.nz), cells / 1e6,
              double(volume.samples().size()) * 4 / (1 << 20));
  std::printf("%-8s %-8s %3s %10s %10s %11s %10s %10s %9s %9s %9s\n", "iso", "algo", "thr", "ms",
              "Mcells/s", "triangles", "vertices", "peak+MiB", "boundary", "nonmanif", "degen");
  for (const std::string& iso_text : split(iso_list)) {
    const float iso = std::stof(iso_text);
    core::TriangleMesh reference;  // the mc surface of this iso, for tm's ratio and distances
    for (const std::string& algorithm : split(algorithms)) {
      for (const std::string& thread_text : split(thread_list)) {
        core::ExtractOptions options;
        options.threads = static_cast<unsigned>(std::stoi(thread_text));
        core::AmbiguityStats ambiguity;
        if (algorithm == "classic") options.mode = core::ExtractOptions::Mode::classic;
        else if (algorithm == "mc") options.stats = &ambiguity;
        else if (algorithm != "tm") return usage();
        std::vector<double> times;
        core::TriangleMesh mesh;
        long peak_added = 0;
        for (int r = 0; r < repeat; ++r) {
          mesh = {};
          ambiguity = {};
          const long before = current_memory_kib();
          reset_peak_memory();
          const auto start = std::chrono::steady_clock::now();
          mesh = algorithm == "tm" ? core::extract_type_merged(volume, iso, options)
                                   : core::extract_isosurface(volume, iso, options);
          const auto end = std::chrono::steady_clock::now();
          peak_added = std::max(peak_added, peak_memory_kib() - before);
          times.push_back(std::chrono::duration<double, std::milli>(end - start).count());
        }
        std::sort(times.begin(), times.end());
        const double median = times[times.size() / 2];
        const core::MeshCheck check = core::check_mesh(mesh);
        std::printf("%-8s %-8s %3s %10.1f %10.1f %11zu %10zu %10.1f %9zu %9zu %9zu\n",
                    iso_text.c_str(), algorithm.c_str(), thread_text.c_str(), median,
                    cells / median / 1e3, mesh.triangles.size(), mesh.positions.size(),
                    double(peak_added) / 1024, check.boundary_edges,
                    check.non_manifold_edges + check.non_manifold_vertices,
                    check.degenerate_triangles);
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
        if (algorithm == "tm" && !reference.empty() && thread_text == split(thread_list).front()) {
          const core::MeshCheck mc_check = core::check_mesh(reference);
          const auto voxels = core::mesh_distance(reference, mesh);
          core::TriangleMesh reference_mm = reference, mesh_mm = mesh;
          core::to_patient(reference_mm, volume.geometry());
          core::to_patient(mesh_mm, volume.geometry());
          const auto mm = core::mesh_distance(reference_mm, mesh_mm);
          std::printf("    tm/mc triangles %.1f%%; Hausdorff %.3f voxel (%.3f mm), mean %.4f voxel "
                      "(%.4f mm); Euler %lld vs %lld, components %zu vs %zu\n",
                      100.0 * double(mesh.triangles.size()) / double(reference.triangles.size()),
                      voxels.hausdorff(), mm.hausdorff(), voxels.mean(), mm.mean(),
                      static_cast<long long>(check.euler_characteristic),
                      static_cast<long long>(mc_check.euler_characteristic), check.components,
                      mc_check.components);
        }
      }
    }
  }
  return 0;
}
