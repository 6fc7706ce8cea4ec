// smooth_mesh: Taubin λ|μ smoothing (Taubin 1995, "A signal processing approach to fair
// surface design"), which removes high-frequency noise without the shrinkage of repeated
// Laplacian smoothing; the plain Laplacian is offered for comparison.
//
// Each Taubin iteration is two umbrella steps with uniform weights,
//   p ← p + λ·L(p)   then   p ← p + μ·L(p),   L(p) = mean(neighbours) − p,
// with λ > 0 and μ < −λ < 0 chosen from the pass-band frequency k_PB:
//   1/λ + 1/μ = k_PB   ⇒   μ = 1 / (k_PB − 1/λ).
// Frequencies below k_PB pass almost unchanged (so the volume is kept); above it they are
// damped. Neighbours are the vertices sharing an edge, so vertices shared by two shells at
// a lattice edge are smoothed across both. Boundary vertices (of open meshes) move too.
#pragma once

#include "core/mesh.h"
#include "mesh/validity.h"

namespace typemerge::mesh {

struct SmoothingOptions {
  enum class Method {
    taubin,     // λ then μ per iteration: keeps the volume
    laplacian,  // λ only per iteration: shrinks; for comparison and tests
  };
  Method method = Method::taubin;
  int iterations = 10;     // >= 0
  double lambda = 0.5;     // in (0, 1]
  double pass_band = 0.1;  // k_PB in (0, 1/λ); usual 0.01 … 0.1
};

struct SmoothingReport {
  int iterations = 0;
  double lambda = 0.0;
  double mu = 0.0;  // 0 for the Laplacian
  double volume_before = 0.0;
  double volume_after = 0.0;
  double relative_volume_change = 0.0;  // (after − before) / |before|, 0 when before is 0
  Validity validity;                     // of the result
};

// Smooths positions in place and recomputes vertex normals (area-weighted); connectivity is
// unchanged. Preconditions: as stated on SmoothingOptions; indices < positions.size().
SmoothingReport smooth_mesh(core::TriangleMesh& mesh, const SmoothingOptions& options = {});

}  // namespace typemerge::mesh
