// Distances between two triangle meshes, for reporting how far a simplified surface (type
// merging, decimation) departs from the marching-cubes surface it came from.
//
// The one-sided distance samples the vertices of `from` and measures each one's exact
// Euclidean distance to the surface (the triangles) of `to`; the symmetric figures run it both
// ways. Vertex sampling is what the type-merging ε bound (MergeOptions::epsilon_voxels) is
// stated for: every MC vertex lies within ε of the merged mesh, i.e.
// vertex_to_mesh_distance(mc, merged).max <= ε.
//
// Cost: a uniform grid of triangle buckets over `to` (about two triangles per cell, CSR, 4
// bytes per bucket entry + 4 per cell), then per point a search in growing shells of cells that
// stops once no unvisited cell can be nearer; about 1 s per million points on one thread for
// CT surfaces, split over `threads`. Results do not depend on the thread count.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/mesh.h"

namespace typemerge::core {

struct MeshDistance {
  double max = 0.0;   // largest vertex-to-surface distance, in the meshes' units
  double mean = 0.0;  // mean over the vertices
  std::size_t points = 0;
};

// Distances from every vertex of `from` to the surface of `to`. An empty `from` gives zeros;
// an empty `to` (with a non-empty `from`) gives infinity. threads: 0 = hardware concurrency.
MeshDistance vertex_to_mesh_distance(const TriangleMesh& from, const TriangleMesh& to,
                                     unsigned threads = 0);

// The distance from each point to the surface of `to` (rounded to float), in order, or `cap`
// for a point farther than cap (the search stops there: far points cost little); infinity for
// every point when `to` has no triangle. Same grid and cost as vertex_to_mesh_distance.
std::vector<float> point_to_mesh_distances(
    std::span<const std::array<float, 3>> points, const TriangleMesh& to, unsigned threads = 0,
    double cap = std::numeric_limits<double>::infinity());

// vertex_to_mesh_distance(from, to).max.
double max_vertex_distance(const TriangleMesh& from, const TriangleMesh& to, unsigned threads = 0);

struct SymmetricMeshDistance {
  MeshDistance a_to_b;
  MeshDistance b_to_a;
  double hausdorff() const { return a_to_b.max > b_to_a.max ? a_to_b.max : b_to_a.max; }
  // Mean over the vertices of both meshes.
  double mean() const;
};

// Both directions (vertex-sampled symmetric Hausdorff distance and mean distance).
SymmetricMeshDistance mesh_distance(const TriangleMesh& a, const TriangleMesh& b,
                                    unsigned threads = 0);

// Points spread over the surface: each triangle's corners and a barycentric lattice inside it,
// k + 1 points along each edge with k = ceil(longest edge / spacing), so no point of the
// surface is farther than about `spacing` from a sample. As vertices of a mesh without
// triangles, for vertex_to_mesh_distance. Every vertex of a merged surface is a vertex of the
// surface it came from, so vertex samples alone miss the insides of merged polygons.
TriangleMesh surface_samples(const TriangleMesh& mesh, double spacing);

// mesh_distance over surface_samples of both meshes: the symmetric Hausdorff and mean
// distances of the surfaces (to within `spacing`).
SymmetricMeshDistance surface_distance(const TriangleMesh& a, const TriangleMesh& b,
                                       double spacing, unsigned threads = 0);

// Points spread over the surface by area, as the project states sampled distances: every
// vertex, every triangle's centroid, then ⌈area × per_unit_area⌉ points in all, uniform over
// the surface: triangle by triangle, each gets the points its share of the area brings the
// running total to (so a small triangle may get none, and the total is exact), at positions
// uniform inside it drawn from (seed, triangle index). The same mesh and seed give the same
// points. Far fewer than surface_samples' lattice, laid out triangle by triangle: a 0.7 mm
// lattice put 12 points on each mm² of the abdomen's bone surfaces (docs/benchmarks.md).
TriangleMesh area_samples(const TriangleMesh& mesh, double per_unit_area, std::uint64_t seed = 1);

// mesh_distance over area_samples of both meshes (both with `seed`).
SymmetricMeshDistance area_sampled_distance(const TriangleMesh& a, const TriangleMesh& b,
                                            double per_unit_area, unsigned threads = 0,
                                            std::uint64_t seed = 1);

namespace detail {

// Squared distance from point p to segment [a, b] (a point when a == b).
double point_segment_distance_squared(const std::array<double, 3>& p,
                                      const std::array<double, 3>& a,
                                      const std::array<double, 3>& b);

// Squared distance from point p to triangle (a, b, c) (Ericson, Real-Time Collision
// Detection §5.1.5); correct for degenerate triangles too.
double point_triangle_distance_squared(const std::array<double, 3>& p,
                                       const std::array<double, 3>& a,
                                       const std::array<double, 3>& b,
                                       const std::array<double, 3>& c);

}  // namespace detail

}  // namespace typemerge::core
