// decimate_mesh: bounded quadric decimation with OpenMesh's decimater (Garland & Heckbert 1997
// quadrics for the order; half-edge collapses, so every vertex of the result is a vertex of the
// input). Not a step of `convert`: --reduce-to and --max-error are type merging itself
// (core/bounded_reduction.h). This is the decimation users run after marching cubes, kept as
// the baseline the benchmarks measure type merging against (bench/reduction_bench.cpp); its
// guarantees hold by construction (link condition, every input vertex within max_error, no
// fold-over).
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
// Hausdorff module re-measures the points of every affected face per candidate. Figures:
// docs/benchmarks.md ("Moved from headers and the README"); tests/mesh/mesh_bench.cpp --stl
// prints them.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "mesh/validity.h"

namespace typemerge::mesh {

struct DecimationOptions {
  // Stop at this many triangles (0: decimate as far as the bounds allow). A closed mesh
  // loses two triangles per collapse, so the result may end one below an odd target.
  std::size_t target_triangles = 0;
  // Hausdorff tolerance in mesh units (mm after to_patient); must be > 0. Pass
  // std::numeric_limits<double>::infinity() to decimate blindly on purpose.
  double max_error = 0.1;
  // Largest normal turn of any face in one collapse, degrees, in (0, 180].
  double max_normal_deviation = 60.0;
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
  double openmesh_ms = 0.0;  // OpenMesh's decimater (0 when it did not run)
};

// Decimates `mesh` in place as described above; vertex normals of the result are recomputed
// (area-weighted). Preconditions: options as documented above; indices < positions.size().
DecimationReport decimate_mesh(core::TriangleMesh& mesh, const DecimationOptions& options = {});

}  // namespace typemerge::mesh
