// Fuzz target: random small volumes (at most 8×8×8) and iso values through the three
// extractors: consistent marching cubes, classic marching cubes and type merging.
//
// Properties (checked with core::check_mesh; a violation aborts):
//  * every triangle index is a vertex of the mesh, for all three;
//  * consistent mode with closed borders: closed, manifold, consistently oriented, no
//    degenerate triangle; with open borders the same except boundary edges;
//  * type merging, in pieces of 1 to 4 layers and blocks of 2 to 8 cubes (shaped by one of
//    four spacings), keeps those guarantees and the Euler characteristic and number of
//    components of the marching-cubes mesh it merges, and stays within epsilon of it
//    (sampled over both surfaces);
//  * threads > 1 give the serial output exactly (extraction and type merging);
//  * no two triangles cross (exact predicates), in marching cubes and in type merging.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "core/marching_cubes.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "core/type_merging.h"
#include "fuzz_input.h"

namespace {

using namespace typemerge::core;
using typemerge::fuzz::FuzzInput;

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_extract: property violated: %s\n", property);
  std::abort();
}

// Samples drawn from a value scheme chosen by the input: a few levels (ties with the iso
// value everywhere), bytes, HU-like shorts, or any finite float.
float sample(FuzzInput& in, unsigned scheme) {
  switch (scheme) {
    case 0: return static_cast<float>(in.pick(4));
    case 1: return static_cast<float>(static_cast<std::int8_t>(in.byte()));
    case 2: return static_cast<float>(in.raw<std::int16_t>());
    default: {
      const float value = in.raw<float>();
      return std::isfinite(value) ? value : 0.0f;
    }
  }
}

void check_indices(const TriangleMesh& mesh) {
  for (const auto& t : mesh.triangles) {
    for (std::uint32_t v : t) {
      if (v >= mesh.positions.size()) violated("a triangle index past the vertices");
    }
  }
  if (mesh.normals.size() != mesh.positions.size()) violated("normals and positions differ in count");
}

void check_sound(const MeshCheck& check, bool closed, const char* what) {
  const bool sound = check.non_manifold_edges == 0 && check.inconsistent_edges == 0 &&
                     check.non_manifold_vertices == 0 && check.degenerate_triangles == 0;
  if (!sound || (closed && check.boundary_edges != 0)) {
    std::fprintf(stderr,
                 "%s: boundary %zu, non-manifold edges %zu, vertices %zu, inconsistent %zu, "
                 "degenerate %zu\n",
                 what, check.boundary_edges, check.non_manifold_edges,
                 check.non_manifold_vertices, check.inconsistent_edges,
                 check.degenerate_triangles);
    violated(closed ? "mesh not closed manifold" : "mesh not manifold");
  }
}

bool same(const TriangleMesh& a, const TriangleMesh& b) {
  return a.positions == b.positions && a.normals == b.normals && a.triangles == b.triangles;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzInput in(data, size);
  const std::uint8_t settings = in.byte();
  const unsigned scheme = settings & 3;
  const bool close_borders = (settings & 4) == 0;
  const bool try_threads = (settings & 8) != 0;
  const VolumeSize volume_size{in.pick(9), in.pick(9), in.pick(9)};
  // Spacings that shape type merging's blocks (MergeOptions::blocks_follow_spacing): even,
  // thick slices, coarse rows and columns, and three different steps.
  constexpr std::array<std::array<double, 3>, 4> kSpacings{
      {{1.0, 1.0, 1.0}, {0.7, 0.7, 3.0}, {3.2, 3.2, 1.5}, {0.5, 1.0, 2.5}}};
  const std::array<double, 3>& step = kSpacings[in.pick(4)];
  IndexToPatient geometry;
  geometry.axes = {{{step[0], 0, 0}, {0, step[1], 0}, {0, 0, step[2]}}};
  Volume volume(volume_size, geometry);
  const float iso = sample(in, scheme) + (in.flag() ? 0.5f : 0.0f);
  for (float& v : volume.samples()) v = sample(in, scheme);

  ExtractOptions options;
  options.close_borders = close_borders;
  const TriangleMesh mc = extract_isosurface(volume, iso, options);
  check_indices(mc);
  const MeshCheck mc_check = check_mesh(mc);
  check_sound(mc_check, close_borders, "consistent");

  if (try_threads) {
    ExtractOptions threaded = options;
    threaded.threads = 3;
    if (!same(extract_isosurface(volume, iso, threaded), mc)) {
      violated("threaded extraction differs from serial");
    }
  }

  ExtractOptions classic = options;
  classic.mode = ExtractOptions::Mode::classic;
  const TriangleMesh classic_mesh = extract_isosurface(volume, iso, classic);
  check_indices(classic_mesh);
  (void)check_mesh(classic_mesh);

  // Pieces of 1 to 4 cube layers: most vertices lie on or near a seam.
  MergeOptions merge;
  merge.slab_layers = 1 + static_cast<unsigned>(in.pick(4));
  merge.block_cubes = 2u << in.pick(3);
  const TriangleMesh tm = extract_type_merged(volume, iso, options, merge);
  check_indices(tm);
  if (try_threads) {
    MergeOptions threaded = merge;
    threaded.threads = 3;
    if (!same(extract_type_merged(volume, iso, options, threaded), tm)) {
      violated("type merging with threads differs from serial");
    }
  }
  const MeshCheck tm_check = check_mesh(tm);
  check_sound(tm_check, close_borders, "type merged");
  if (close_borders && (tm_check.euler_characteristic != mc_check.euler_characteristic ||
                        tm_check.components != mc_check.components)) {
    violated("type merging changed the topology");
  }
  if (!mc.empty() && surface_distance(mc, tm, 0.25, 1).hausdorff() > merge.epsilon_voxels + 1e-4) {
    violated("type merging left the marching-cubes surface by more than epsilon");
  }
  // No two triangles cross (exact predicates): both by construction (cubes, blocks).
  if (!find_self_intersections(mc).pairs.empty()) violated("marching cubes made crossing triangles");
  if (!find_self_intersections(tm).pairs.empty()) violated("type merging made crossing triangles");
  return 0;
}
