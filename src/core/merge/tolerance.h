// The bound a merge keeps, in the units the caller states it in: voxels of index space (ε
// along any direction of the lattice, the default) or millimetres of patient space. How a
// disk's slab and a thinned chord's offset count against it.
//
// In voxels: a disk is flat when its slab along its unit normal n is at most ε thick, and
// thinning between disks of thicknesses w₁, w₂ may offset a face chord by δ = sqrt(ε² − w²),
// w = max(w₁, w₂) (the offset lies across n, the slab along it: orthogonal in index space).
// In millimetres (a grid whose index step along axis a is axes[a] mm): points a disk and its
// replacement pair up along n (index space), so a slab w thick spans w·|A n| mm, A the matrix
// of the axes; an offset of δ index units across n spans at most σ·δ mm, σ the largest
// stretch of A (bounded above by Gershgorin's row sums of AᵀA: exact on orthogonal grids,
// the largest spacing); the two add (A need not keep them orthogonal), so
// δ = (ε − w_mm) / σ with w_mm the larger of the two disks' spans.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "core/merge/geometry.h"

namespace typemerge::core::merge {

class Tolerance {
 public:
  static Tolerance in_voxels(double epsilon) { return Tolerance(epsilon, false, {}, 1.0); }
  static Tolerance in_mm(double epsilon_mm, const std::array<P3, 3>& axes) {
    double stretch = 0.0;
    for (int i = 0; i < 3; ++i) {
      double row = 0.0;
      for (int j = 0; j < 3; ++j) row += std::fabs(dot(axes[i], axes[j]));
      stretch = std::max(stretch, row);
    }
    return Tolerance(epsilon_mm, true, axes, std::sqrt(stretch));
  }

  double epsilon() const { return epsilon_; }
  bool in_mm() const { return in_mm_; }

  // What a slab `width` index units thick along the unit normal n spans, in ε's units.
  double span(double width, const P3& n) const {
    if (!in_mm_) return width;
    P3 v{0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      for (int c = 0; c < 3; ++c) v[c] += n[a] * axes_[a][c];
    }
    return width * std::sqrt(dot(v, v));
  }

  // How far (index units) thinning may offset a chord in a face two disks share, their slabs
  // spanning band_a and band_b (ε's units); 0 when a slab spans all of ε.
  double thinning_tolerance(double band_a, double band_b) const {
    const double band = std::max(band_a, band_b);
    if (!in_mm_) return std::sqrt(std::max(0.0, epsilon_ * epsilon_ - band * band));
    return std::max(0.0, epsilon_ - band) / stretch_;
  }

 private:
  Tolerance(double epsilon, bool in_mm, const std::array<P3, 3>& axes, double stretch)
      : epsilon_(epsilon), in_mm_(in_mm), axes_(axes), stretch_(stretch) {}

  double epsilon_;
  bool in_mm_;
  std::array<P3, 3> axes_;
  double stretch_;  // σ: the largest stretch of the axes (mm per index unit), at least
};

}  // namespace typemerge::core::merge
