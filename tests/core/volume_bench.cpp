// Throughput of extract_isosurface and extract + merge_types on a raw-float NRRD volume (as
// written by `extract_bench --write-nrrd`) or an analytic sphere, for a list of thread counts,
// with a hash of every output so that "identical to one thread" and "identical to before the
// change" can be checked from the command line. Not a test: never gates.
//
//   volume_bench (--nrrd FILE | --sphere N) [--iso 300,-500] [--threads 1,2] [--repeat 5]
//                [--merge 1] [--distance 0] [--max-class N (MergeOptions::max_class_vertices)];
//                --threads applies to MC (merge_types is serial)
//
// Cells are (nx − 1)(ny − 1)(nz − 1), as in bench/extract_bench. Prints min and median ms.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh_distance.h"
#include "core/type_merging.h"
#include "test_volumes.h"

namespace {

using namespace typemerge::core;

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) out.push_back(item);
  return out;
}

// Minimal reader for the NRRD files io::write_nrrd writes: "type: float", raw, little endian.
bool read_nrrd(const std::string& path, Volume& volume) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::int64_t nx = 0, ny = 0, nz = 0;
  bool is_float = false;
  while (std::getline(in, line) && !line.empty()) {
    if (line.rfind("sizes:", 0) == 0) {
      std::stringstream(line.substr(6)) >> nx >> ny >> nz;
    } else if (line == "type: float") {
      is_float = true;
    }
  }
  if (!is_float || nx <= 0 || ny <= 0 || nz <= 0) return false;
  volume = Volume({nx, ny, nz}, IndexToPatient{});
  in.read(reinterpret_cast<char*>(volume.samples().data()),
          static_cast<std::streamsize>(volume.samples().size() * sizeof(float)));
  return static_cast<bool>(in);
}

std::uint64_t hash_bytes(std::uint64_t h, const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

std::uint64_t hash_mesh(const TriangleMesh& mesh) {
  std::uint64_t h = 14695981039346656037ull;
  h = hash_bytes(h, mesh.positions.data(), mesh.positions.size() * sizeof(mesh.positions[0]));
  h = hash_bytes(h, mesh.normals.data(), mesh.normals.size() * sizeof(mesh.normals[0]));
  h = hash_bytes(h, mesh.triangles.data(), mesh.triangles.size() * sizeof(mesh.triangles[0]));
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  using Clock = std::chrono::steady_clock;
  std::string nrrd, iso_list = "300,-500", thread_list = "1";
  std::int64_t sphere = 0;
  int repeat = 5;
  bool merge = true;
  bool distance = false;
  long max_class = -1;  // -1: the MergeOptions default
  for (int a = 1; a + 1 < argc; a += 2) {
    const std::string key = argv[a], value = argv[a + 1];
    if (key == "--nrrd") nrrd = value;
    else if (key == "--sphere") sphere = std::stoll(value);
    else if (key == "--iso") iso_list = value;
    else if (key == "--threads") thread_list = value;
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--merge") merge = value != "0";
    else if (key == "--distance") distance = value != "0";
    else if (key == "--max-class") max_class = std::stol(value);
    else {
      std::fprintf(stderr, "unknown option %s\n", key.c_str());
      return 2;
    }
  }
  Volume volume;
  if (!nrrd.empty()) {
    if (!read_nrrd(nrrd, volume)) {
      std::fprintf(stderr, "cannot read %s\n", nrrd.c_str());
      return 1;
    }
  } else if (sphere > 0) {
    const double centre = 0.5 * static_cast<double>(sphere - 1) + 0.13;
    volume = test::sphere_volume(sphere, 0.4 * static_cast<double>(sphere), centre,
                                 centre - 0.21, centre + 0.07);
    iso_list.assign(1, '0');
  } else {
    std::fprintf(stderr, "usage: volume_bench (--nrrd FILE | --sphere N) [--iso a,b] "
                         "[--threads 1,2] [--repeat 5] [--merge 1] [--distance 0] "
                         "[--max-class N]\n");
    return 2;
  }
  const VolumeSize& s = volume.size();
  const double cells = double(s.nx - 1) * double(s.ny - 1) * double(s.nz - 1);
  std::printf("volume %lldx%lldx%lld (%.1f M cells), repeat %d\n", static_cast<long long>(s.nx),
              static_cast<long long>(s.ny), static_cast<long long>(s.nz), cells * 1e-6, repeat);
  for (const std::string& iso_text : split(iso_list)) {
    const float iso = std::stof(iso_text);
    for (const std::string& thread_text : split(thread_list)) {
      ExtractOptions options;
      options.threads = static_cast<unsigned>(std::stoul(thread_text));
      std::vector<double> mc_ms;
      std::vector<double> merge_ms;
      TriangleMesh mesh;
      TriangleMesh mc;
      std::vector<BoundaryCube> cubes;
      MergeStats stats;
      std::uint64_t mc_hash = 0;
      for (int r = 0; r < repeat; ++r) {
        ExtractOptions with_cubes = options;
        if (merge) with_cubes.cubes = &cubes;
        const auto t0 = Clock::now();
        mesh = extract_isosurface(volume, iso, with_cubes);
        const auto t1 = Clock::now();
        mc_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        if (r == 0) {
          if (distance) mc = mesh;
          mc_hash = hash_mesh(mesh);
          for (const BoundaryCube& c : cubes) {  // field by field: the struct has padding
            const std::int32_t fields[5] = {c.x, c.y, c.z, c.index,
                                            static_cast<std::int32_t>(c.first_triangle)};
            mc_hash = hash_bytes(mc_hash, fields, sizeof(fields));
          }
        }
        if (merge) {
          const auto t2 = Clock::now();
          MergeOptions merge_options;
          if (max_class >= 0) merge_options.max_class_vertices = static_cast<std::uint32_t>(max_class);
          merge_types(mesh, cubes, merge_options, &stats);
          const auto t3 = Clock::now();
          merge_ms.push_back(std::chrono::duration<double, std::milli>(t3 - t2).count());
        }
      }
      std::sort(mc_ms.begin(), mc_ms.end());
      std::sort(merge_ms.begin(), merge_ms.end());
      std::printf("iso %-6s threads %-2s MC %7.1f ms min %7.1f median %6.1f Mcells/s, %zu tri, "
                  "hash %016llx\n",
                  iso_text.c_str(), thread_text.c_str(), mc_ms.front(), mc_ms[mc_ms.size() / 2],
                  cells / mc_ms.front() * 1e-3, stats.triangles_before,
                  static_cast<unsigned long long>(mc_hash));
      if (merge) {
        const double total = mc_ms.front() + merge_ms.front();
        std::printf("                     merge %7.1f ms min %7.1f median; MC+TM %7.1f ms %6.1f "
                    "Mcells/s, %zu tri, hash %016llx\n",
                    merge_ms.front(), merge_ms[merge_ms.size() / 2], total, cells / total * 1e-3,
                    mesh.triangles.size(), static_cast<unsigned long long>(hash_mesh(mesh)));
        std::printf("                     collapses %zu of %zu tried, slivers removed %zu left "
                    "%zu, merges abandoned %zu, capped %zu\n",
                    stats.collapses_done, stats.collapses_tried, stats.sliver_collapses,
                    stats.slivers_left, stats.merges_abandoned, stats.runs_capped);
        if (distance) {
          const auto t0 = Clock::now();
          const SymmetricMeshDistance d = mesh_distance(mc, mesh, options.threads);
          const double ms =
              std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
          std::printf("                     distance MC->TM max %.4f mean %.5f, TM->MC max %.4f "
                      "mean %.5f, Hausdorff %.4f voxel (%.0f ms)\n",
                      d.a_to_b.max, d.a_to_b.mean, d.b_to_a.max, d.b_to_a.mean, d.hausdorff(), ms);
        }
      }
    }
  }
}
