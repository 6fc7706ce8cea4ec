// extract_inner_wall: the inner wall of a hollowed model (`convert --hollow MM`) — the
// surface at distance `wall_mm` inside a finished outer surface, wound inward, to be appended
// to it as a cavity so that the model becomes a shell of that wall thickness.
//
// The inner wall is the iso-surface at level wall_mm of F, the distance from a voxel centre
// to the outer surface, extracted with the consistent marching cubes (closed, manifold):
//   1. mask: the samples inside the outer surface's extraction (value >= iso), the same
//      samples the outer surface was extracted from; with fill_enclosed, with the enclosed
//      air pockets filled as the finishing filled the surface's cavities;
//   2. D: the exact Euclidean distance (mm) from each sample to the nearest outside sample,
//      everything beyond the volume border outside (distance_transform.h, anisotropic);
//   3. F: D counts voxel centres, but the outer surface lies between them (and the finishing
//      steps moved it a little), so in a band around F = wall_mm, F is the exact distance from
//      the voxel centre to the outer surface's triangles (mesh_distance.h). Outside the band a
//      lower bound stands in (deeper samples: above wall_mm; shallower: below), which can only
//      move the wall's crossings deeper, never thinner;
//   4. extraction at level wall_mm + r²/(8·wall_mm) (r: the voxel diagonal; the chord error
//      of interpolating F across a cube near a convex bend, added so that the wall is not
//      thinner there), to patient mm, triangles reversed (facing inward);
//   5. components: those outside the outer surface (the inside of a component the finishing
//      removed) and hollows enclosing less than wall_mm³ (thin parts where the wall is almost
//      everything) are dropped.
//
// Guarantee, up to the linear interpolation of F inside cubes (F is 1-Lipschitz; the chord
// error, at most about r²/(8·wall_mm) near convex bends of the outer surface where F is a
// distance to a point or an edge, is added to the level; elsewhere it is zero or on the safe
// side): every point of the inner wall lies at distance >= wall_mm from the outer surface, so
// the walls never cross; the wall is on average about r²/(8·wall_mm) + a third of a voxel
// thicker than asked. Measured in
// tests/core/inner_wall_test.cpp and tests/app/hollow_test.cpp.
//
// Band: samples with (wall_mm − m)/σ_max <= D <= (wall_mm + r + m)/σ_min, where r is the voxel
// diagonal (the farthest a marching-cubes surface point is from an outside voxel centre), m =
// outer_deviation_mm and σ bound the stretch of a sheared grid (1 for an orthogonal one).
// Memory, in slabs (InnerWallOptions::slab_layers, the default): a float scratch of a slab's
// slices and a halo of ceil(reach / slice step) + 1 slices on each side, where reach is the
// band's top + 4 cube diagonals + a step (distances are exact up to it, and no value the
// extraction reads depends on deeper ones), + F on the slab's slices only (its pages are
// returned once extracted), + 20 bytes a band sample of a slab + the inner mesh — bounded in
// the slice count. With fill_enclosed (or slab_layers 0): 4 bytes a voxel (the whole field),
// 1 + a stack for fill_enclosed, + 20 bytes a band sample + the inner mesh. Exact distances
// are searched up to the band's top only. Cost: the distance transform (three passes over
// the volume, the halo's slices again per slab) + about 1 µs per band sample; in slabs the
// wall's extraction runs on one thread.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/mesh.h"
#include "core/volume.h"

namespace typemerge::core {

struct InnerWallOptions {
  double wall_mm = 0;  // > 0
  // How far the outer surface may lie from the marching-cubes surface of the mask (type
  // merging's ε, smoothing, decimation error), in mm: widens the band.
  double outer_deviation_mm = 0;
  unsigned threads = 0;  // 0 = hardware concurrency; the result does not depend on it
  // The outer surface's cavities were filled: outside samples not joined to the volume's
  // border (6-connected) count as inside, so the air pockets inside get no wall.
  bool fill_enclosed = false;
  // Cube layers per slab: the distances and F are computed, and the wall extracted, slab by
  // slab (0: the whole volume at once; fill_enclosed also works on the whole volume, whose
  // outside connectivity it needs). The result is the same bytes for every value.
  std::int64_t slab_layers = 16;
};

struct InnerWallStats {
  std::size_t band_samples = 0;          // samples whose distance was measured exactly
  std::size_t components = 0;            // of the extracted wall
  std::size_t dropped_outside = 0;       // components outside the outer surface
  std::size_t dropped_small = 0;         // hollows enclosing less than wall_mm³
  double hollow_volume_mm3 = 0;          // enclosed by the kept inner wall (>= 0)
};

// `field` and `iso`: what the outer surface was extracted from (value >= iso inside, closed
// borders); `outer`: the finished outer surface in patient mm (closed, wound outward). Returns
// the inner wall in patient mm, wound inward (empty when the wall fills the whole solid), with
// gradient vertex normals (pointing into the hollow) only when `outer` has normals.
// Precondition: options.wall_mm > 0, field.geometry().determinant() != 0.
TriangleMesh extract_inner_wall(const Volume& field, float iso, const TriangleMesh& outer,
                                const InnerWallOptions& options, InnerWallStats* stats = nullptr);

}  // namespace typemerge::core
