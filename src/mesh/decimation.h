// decimate_mesh: bounded quadric decimation (Garland & Heckbert 1997 quadrics for the order;
// half-edge collapses, so every vertex of the result is a vertex of the input) by one of two
// libraries:
//  * OpenMesh's decimater (the default; decimate_with_openmesh, below): its guarantees hold by
//    construction (link condition, every input vertex within max_error, no fold-over).
//  * meshoptimizer (--decimator meshopt; mesh/meshopt_decimation.h): a much faster simplifier,
//    but its bound is a mean quadric error and it has no link-condition test, so its result is
//    checked after and repaired by passes that keep the input around each problem; when that
//    does not converge the input goes to OpenMesh (`fallback` says why).
// Why OpenMesh stays the default: on CT bone meshoptimizer's result keeps failing those checks
// (triangles on non-manifold edges or vertices, zero-area triangles, points beyond the bound),
// so it falls back, and its checks cost about as much as OpenMesh alone.
//
// OpenMesh's modules, in its terms:
//  * ModQuadricT (priority, no bound): collapses the edge of least area-weighted quadric
//    error first;
//  * ModHausdorffT (binary): a collapse is allowed only while every original vertex that
//    was removed stays within max_error of the faces that now cover it — so the stated
//    bound holds for all input vertices: distance(input vertex, result) <= max_error;
//  * ModNormalFlippingT (binary): no face normal turns by more than max_normal_deviation
//    in one collapse, which rules out fold-overs.
// OpenMesh's collapse test (link condition, no boundary edge collapsed into an interior one)
// keeps a closed manifold closed and manifold with the same Euler characteristic.
//
// Input that OpenMesh cannot hold (a face on an edge used in the same direction twice, or
// by more than two faces) is not decimated: the mesh is returned unchanged with a warning,
// since leaving the rejected faces out would open holes. Non-manifold vertices are split
// per fan before decimating (see detail/openmesh_conversion.h) and stay split.
//
// Speed: OpenMesh's decimater is a single-threaded heap over half-edge collapses, and the
// Hausdorff module re-measures the points of every affected face per candidate, which makes it
// a conversion's slowest step when asked for. Figures of both libraries: docs/benchmarks.md
// ("Moved from headers and the README"); tests/mesh/mesh_bench.cpp --stl prints them.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "mesh/validity.h"

namespace typemerge::mesh {

enum class Decimator { meshopt, openmesh };
const char* to_string(Decimator decimator);  // "meshopt", "openmesh"

struct DecimationOptions {
  // Stop at this many triangles (0: decimate as far as the bounds allow). A closed mesh
  // loses two triangles per collapse, so the result may end one below an odd target.
  std::size_t target_triangles = 0;
  // Hausdorff tolerance in mesh units (mm after to_patient); must be > 0. Pass
  // std::numeric_limits<double>::infinity() to decimate blindly on purpose.
  double max_error = 0.1;
  // Largest normal turn of any face in one collapse, degrees, in (0, 180] (OpenMesh only;
  // meshoptimizer refuses any collapse that flips a face by more than 90°).
  double max_normal_deviation = 60.0;
  // Which library to try first; meshopt falls back to openmesh when its result fails a check.
  Decimator decimator = Decimator::openmesh;
  // Threads for meshopt's checks (0: hardware concurrency); OpenMesh is single-threaded.
  unsigned threads = 0;
};

// What the meshoptimizer path did (all zero when it was not tried).
struct MeshoptAttempt {
  int passes = 0;  // meshopt_simplify runs (each pass keeps the last one's problems)
  std::size_t kept_triangles = 0;  // input triangles meshopt kept around problems
  std::vector<std::string> notes;  // per pass that found problems: what, how many
  // Its checks: the sampled two-sided distance of its result to the input (mm, capped at
  // 2 max_error; see mesh/meshopt_decimation.h), negative when not measured, and the crossing
  // pairs of its result.
  double sampled_error = -1.0;
  std::size_t crossing_pairs = 0;
  double simplify_ms = 0.0;  // meshopt_simplify, all passes
  double check_ms = 0.0;     // its checks, all passes
};

struct DecimationReport {
  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  double max_error = 0.0;      // the bound used
  bool reached_target = false;  // false when the bounds stopped it first (or no target)
  std::size_t split_vertices = 0;      // non-manifold vertices split before decimating
  std::size_t rejected_triangles = 0;  // faces OpenMesh could not hold (then nothing done)
  std::vector<std::string> warnings;
  Validity validity;  // of the result

  Decimator decimator = Decimator::openmesh;  // the library whose result this is
  // Why meshoptimizer's result was refused, e.g. "3 non-manifold edges" or "sampled distance
  // 0.31 mm > 0.2 mm"; empty when it was accepted or not tried.
  std::string fallback;
  MeshoptAttempt meshopt;  // what meshoptimizer did, also when its result was refused
  double openmesh_ms = 0.0;  // OpenMesh's decimater (0 when it did not run)
};

// Decimates `mesh` in place with options.decimator, falling back from meshopt to OpenMesh as
// described above; vertex normals of the result are recomputed (area-weighted).
// Preconditions: options as documented above; indices < positions.size().
DecimationReport decimate_mesh(core::TriangleMesh& mesh, const DecimationOptions& options = {});

// OpenMesh's decimater alone (options.decimator is ignored).
DecimationReport decimate_with_openmesh(core::TriangleMesh& mesh,
                                        const DecimationOptions& options = {});

}  // namespace typemerge::mesh
