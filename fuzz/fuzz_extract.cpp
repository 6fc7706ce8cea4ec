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
//    (sampled over both surfaces); with a bound in millimetres (blocks up to 32 cubes, also on
//    a sheared grid), within that bound in patient mm; reduced to a triangle count, its count
//    in the window when said met, the topology kept, within the bound it reports, no
//    crossings; merged and collapsed within the bound alone, the same;
//  * threads > 1 give the serial output exactly (extraction and type merging), and type
//    merging reads no slice it has reported done (MergeOptions::slices_done);
//  * no two triangles cross (exact predicates), in marching cubes and in type merging.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <vector>

#include "core/bounded_reduction.h"
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
  // A bound in millimetres (MergeOptions::epsilon_mm), on a sheared grid when bit 5 is set;
  // bit 6: a triangle count (extract_type_merged_to_count) on top; bit 7, with a bound: the
  // merge and its locally limited collapses within it (extract_type_merged_within).
  const bool in_mm = (settings & 16) != 0;
  const bool sheared = (settings & 32) != 0;
  const bool to_count = (settings & 64) != 0;
  const bool within = (settings & 128) != 0;
  const VolumeSize volume_size{in.pick(9), in.pick(9), in.pick(9)};
  // Spacings that shape type merging's blocks (MergeOptions::blocks_follow_spacing): even,
  // thick slices, coarse rows and columns, and three different steps.
  constexpr std::array<std::array<double, 3>, 4> kSpacings{
      {{1.0, 1.0, 1.0}, {0.7, 0.7, 3.0}, {3.2, 3.2, 1.5}, {0.5, 1.0, 2.5}}};
  const std::array<double, 3>& step = kSpacings[in.pick(4)];
  IndexToPatient geometry;
  geometry.axes = {{{step[0], 0, 0}, {0, step[1], 0}, {0, sheared ? 0.4 * step[2] : 0, step[2]}}};
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
  merge.block_cubes = 2u << in.pick(in_mm ? 5 : 3);
  constexpr std::array<double, 4> kBoundsMm{0.3, 1.0, 2.5, 6.0};
  if (in_mm) merge.epsilon_mm = kBoundsMm[in.pick(4)];
  const TriangleMesh tm = extract_type_merged(volume, iso, options, merge);
  check_indices(tm);
  if (try_threads) {
    MergeOptions threaded = merge;
    threaded.threads = 3;
    if (!same(extract_type_merged(volume, iso, options, threaded), tm)) {
      violated("type merging with threads differs from serial");
    }
  }
  if (try_threads) {
    // Slices reported done (MergeOptions::slices_done) are never read again: flipping every
    // sample of them across the iso value as they are reported changes nothing (one thread,
    // so that every later piece is made after the flips), with the idle slice buffers' pages
    // returned. The reports cover every slice exactly once.
    Volume flipped = volume;
    MergeOptions watched = merge;
    watched.threads = 1;  // each piece made after the ones before it are appended
    watched.return_idle_pages = true;
    std::vector<bool> done(static_cast<std::size_t>(volume_size.nz), false);
    watched.slices_done = [&](std::int64_t begin, std::int64_t end) {
      if (begin < 0 || end > volume_size.nz || begin >= end) {
        violated("slices_done reported an empty or out-of-range range");
      }
      for (std::int64_t z = begin; z < end; ++z) {
        if (done[static_cast<std::size_t>(z)]) violated("slices_done reported a slice twice");
        done[static_cast<std::size_t>(z)] = true;
        for (std::int64_t y = 0; y < volume_size.ny; ++y) {
          for (std::int64_t x = 0; x < volume_size.nx; ++x) {
            float& v = flipped.at(x, y, z);
            v = v >= iso ? iso - 1000.0f : iso + 1000.0f;
          }
        }
      }
    };
    if (!same(extract_type_merged(flipped, iso, options, watched), tm)) {
      violated("type merging read a slice it had reported done");
    }
    if (std::find(done.begin(), done.end(), false) != done.end()) {
      violated("slices_done left a slice unreported");
    }
  }
  const MeshCheck tm_check = check_mesh(tm);
  check_sound(tm_check, close_borders, "type merged");
  if (close_borders && (tm_check.euler_characteristic != mc_check.euler_characteristic ||
                        tm_check.components != mc_check.components)) {
    violated("type merging changed the topology");
  }
  if (!in_mm && !mc.empty() &&
      surface_distance(mc, tm, 0.25, 1).hausdorff() > merge.epsilon_voxels + 1e-4) {
    violated("type merging left the marching-cubes surface by more than epsilon");
  }
  if (in_mm && !mc.empty()) {
    TriangleMesh mc_mm = mc;
    TriangleMesh tm_mm = tm;
    to_patient(mc_mm, geometry);
    to_patient(tm_mm, geometry);
    if (surface_distance(mc_mm, tm_mm, 0.25, 1).hausdorff() > merge.epsilon_mm + 1e-3) {
      violated("type merging left the marching-cubes surface by more than its bound in mm");
    }
  }
  // A reduced surface: sound, marching cubes' topology, within `bound` mm, no crossings (in
  // millimetres: the collapses judge crossings on the coordinates written).
  auto check_reduced = [&](const TriangleMesh& reduced, double bound, const char* what) {
    check_indices(reduced);
    const MeshCheck r_check = check_mesh(reduced);
    check_sound(r_check, close_borders, what);
    if (r_check.euler_characteristic != mc_check.euler_characteristic ||
        r_check.components != mc_check.components) {
      violated("a reduction changed the topology");
    }
    TriangleMesh mc_mm = mc;
    TriangleMesh r_mm = reduced;
    to_patient(mc_mm, geometry);
    to_patient(r_mm, geometry);
    if (surface_distance(mc_mm, r_mm, 0.25, 1).hausdorff() > bound + 1e-3) {
      violated("a reduction left the marching-cubes surface by more than its bound");
    }
    if (!find_self_intersections(r_mm).pairs.empty()) violated("a reduction made crossings");
  };
  if (to_count && !mc.empty() && close_borders) {
    const std::size_t target = 1 + in.pick(static_cast<unsigned>(
                                       std::min<std::size_t>(mc.triangles.size(), 255)));
    const ReductionResult r =
        extract_type_merged_to_count(volume, iso, options, merge, target, kBoundsMm[in.pick(4)]);
    if (r.target_met && (r.mesh.triangles.size() > target ||
                         double(r.mesh.triangles.size()) < 0.99 * double(target))) {
      violated("a count said met is outside its window");
    }
    check_reduced(r.mesh, r.bound_mm, "reduced to a count");
  }
  if (within && in_mm && !mc.empty() && close_borders) {
    const ReductionResult r =
        extract_type_merged_within(volume, iso, options, merge, merge.epsilon_mm);
    if (r.mesh.triangles.size() > tm.triangles.size()) violated("collapses added triangles");
    check_reduced(r.mesh, merge.epsilon_mm, "merged and collapsed within a bound");
  }
  // No two triangles cross (exact predicates): both by construction (cubes, blocks).
  if (!find_self_intersections(mc).pairs.empty()) violated("marching cubes made crossing triangles");
  if (!find_self_intersections(tm).pairs.empty()) violated("type merging made crossing triangles");
  return 0;
}
