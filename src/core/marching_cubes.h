// extract_isosurface: topologically consistent marching cubes (the reference extractor of the
// core), after Lorensen & Cline 1987 with ambiguous faces decided by the asymptotic decider
// of Nielson & Hamann 1991 and each cube triangulated by the face-loop construction of
// type-merging-spec.md §5.3 (tables in cube_tables.h).
//
// Conventions:
//  * a sample is inside when value >= iso (state 1, spec §1.1);
//  * surface vertices lie on lattice edges and are shared by every cube around the edge, so
//    the mesh is indexed and crack-free; positions are in voxel index space;
//  * triangles are wound outward (right-hand rule points from inside to outside) and vertex
//    normals are the negated, interpolated central-difference gradient (toward lower values);
//  * ties: a sample equal to iso is inside, but the vertex on an edge is never placed closer
//    than kEdgeMargin (in edge units) to either end, so two vertices never coincide and no
//    triangle has zero area even on integer data with an integral iso.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "core/mesh.h"
#include "core/volume.h"

namespace typemerge::core {

// Counts in the style of Table 4 of Oh & Park 1996.
struct AmbiguityStats {
  std::size_t boundary_cubes = 0;  // cubes with inside and outside corners
  // Boundary cubes by their number of ambiguous faces (only 0, 1, 2, 3 and 6 occur).
  std::array<std::size_t, 7> cubes_with_ambiguous_faces{};
  // Ambiguous faces (counted once per cube that sees them) the decider resolved as joined.
  std::size_t joined_faces = 0;
  // Loops that needed an extra centre vertex (no fan apex avoids the cube faces).
  std::size_t centroid_vertices = 0;

  // Counts of two parts of a surface (slabs, pieces) added up.
  AmbiguityStats& operator+=(const AmbiguityStats& part) {
    boundary_cubes += part.boundary_cubes;
    for (std::size_t k = 0; k < cubes_with_ambiguous_faces.size(); ++k) {
      cubes_with_ambiguous_faces[k] += part.cubes_with_ambiguous_faces[k];
    }
    joined_faces += part.joined_faces;
    centroid_vertices += part.centroid_vertices;
    return *this;
  }
};

// One boundary cube as the extractor triangulated it, for post-processing that needs the
// lattice structure (type merging). Cube (x, y, z) spans [x, x+1] × [y, y+1] × [z, z+1] in
// voxel index space; with close_borders it may start at −1 or at the last sample (the caps).
struct BoundaryCube {
  std::int32_t x = 0;
  std::int32_t y = 0;
  std::int32_t z = 0;
  std::uint8_t index = 0;            // cube index, bit i = vertex vi inside
  std::uint8_t loops = 0;            // its surface's loops (connected pieces in the cube)
  std::uint32_t first_triangle = 0;  // its triangles run up to the next cube's first_triangle
};

struct ExtractOptions {
  enum class Mode {
    // Every ambiguous face decided by the asymptotic decider from its own four values, every
    // cube triangulated to match: closed, manifold, consistently oriented.
    consistent,
    // One fixed triangulation per cube index (spec §5.2): leaves holes where two cubes
    // disagree about a shared ambiguous face. For demonstrating what consistent mode fixes.
    classic,
  };

  // Treat everything outside the volume as outside (below iso), so a surface that meets the
  // volume border is closed by a cap lying kEdgeMargin outside the border samples.
  bool close_borders = true;
  Mode mode = Mode::consistent;
  // When not null, filled with the statistics of this extraction.
  AmbiguityStats* stats = nullptr;
  // When not null, receives every boundary cube in scan order (z, then y, then x), with the
  // range of mesh triangles it produced. Costs 20 bytes per boundary cube.
  std::vector<BoundaryCube>* cubes = nullptr;
  // Worker threads: 0 = std::thread::hardware_concurrency(), 1 = serial. The output (vertex
  // order, triangles, cube records, statistics) is identical for every value.
  unsigned threads = 1;
  // Gradient normals per vertex (mesh.normals); false: mesh.normals is left empty, the rest of
  // the output unchanged. They are about a fifth of marching cubes' instructions, and a
  // conversion never writes them: STL, 3MF and the preview use facet normals from the winding,
  // PLY and OBJ store none, and smoothing and decimation recompute them (figures:
  // docs/benchmarks.md, "Moved from headers and the README").
  bool vertex_normals = true;
  // When set, extract_isosurface calls it once, with every slice [0, nz), as soon as it has
  // read the volume for the last time: before the slabs' meshes are joined, when the mesh is
  // held twice for a moment. A holder that needs the volume no more can release the slices
  // (Volume::release_slices) so that the join does not hold it too. extract_layers and type
  // merging never call it. The output does not depend on it.
  std::function<void(std::int64_t begin, std::int64_t end)> slices_done = nullptr;
};

// Cost and memory (W × H = padded slice size, (nx + 2)(ny + 2) with close_borders):
//  * one classification pass over every sample; every later pass visits, per row, only the x
//    range between the row's first and last crossing (flying-edges trims), so empty rows and
//    empty stretches of rows cost one comparison per sample;
//  * peak memory = the output mesh (+ the cube records when requested) + 31 bytes × W × H per
//    working thread (two slices of values, inside bytes and edge vertex ids, one slice of
//    z-edge ids) — independent of the number of slices. With threads > 1 the slabs' meshes
//    are concatenated at the end, so the mesh is held twice for a moment (parts are freed as
//    they are copied): peak ≤ 2 × mesh + 31 B × W × H × threads.
//  * threads: slabs of whole cube layers, output byte for byte the serial one (see
//    ExtractOptions::threads).

// Smallest distance, as a fraction of the edge, between a surface vertex and a sample.
inline constexpr float kEdgeMargin = 1e-3f;

// Extracts the iso-surface value == iso of `volume` (samples must be finite). An empty or
// too small volume (or one without a crossing) gives an empty mesh.
TriangleMesh extract_isosurface(const Volume& volume, float iso,
                                const ExtractOptions& options = {});

namespace detail {

// The asymptotic decider for one face with corner values a, b, c, d in cyclic order, where
// a and c are inside (>= iso) and b and d outside: true when the bilinear interpolant's
// saddle value is >= iso, i.e. the contour joins a and c across the face. Written without
// the division, (a−iso)(c−iso) >= (b−iso)(d−iso), which is equivalent because the
// denominator a + c − b − d is positive, and symmetric in a↔c and b↔d so both cubes sharing
// the face compute the same answer.
bool face_joins_inside(float a, float b, float c, float d, float iso);

// The extractor's slice arrays (two padded slices' samples, flags and vertex ids, the z-edge
// ids between them: about 22 bytes a padded slice sample, 30 for a float volume) in one block.
// A piece carries its block (SurfacePiece::slice_buffers), so a caller extracting piece after
// piece maps its pages once (a 512 × 512 slice pair is about 1,400 page faults). Not on huge
// pages: x- and y-edge ids are written only where rows are cut, and 2 MiB pages backed them
// all (+4.6 MB of peak on two threads, docs/benchmarks.md).
class SliceBuffers {
 public:
  // At least `bytes` bytes, aligned for any scalar; their contents are unspecified.
  std::byte* reserve(std::size_t bytes);
  // Returns the block's whole pages to the operating system, keeping the block (the next
  // use faults them in again, zeroed): for a holder idle between uses, such as a thread
  // merging the piece it has just extracted. Linux; elsewhere nothing.
  void release_pages();

 private:
  std::unique_ptr<std::byte[]> block_;
  std::size_t bytes_ = 0;
};

// A piece of the surface: the cube layers [first, last) of the lattice (padded by one layer
// on each side with close_borders), extracted alone as extract_isosurface's slabs are. Its
// first shared_vertices vertices lie on slice `first`: when first > 0 they are, in the same
// order, the vertices [top_first, top_end) of the piece that ends at `first` (slice `last` of
// a piece holds exactly those). A piece is open where it is cut (mesh boundary along the
// seam); stitching pieces by those vertices gives extract_isosurface's surface.
struct SurfacePiece {
  TriangleMesh mesh;  // without normals when extracted with defer_normals
  std::vector<BoundaryCube> cubes;  // its boundary cubes, triangles indexed in `mesh`
  // With defer_normals: each vertex's lattice edge (or centre-vertex number), for
  // deferred_vertex_normal, and the centre vertices' normals.
  std::vector<std::uint64_t> vertex_edges;
  std::vector<std::array<float, 3>> centroid_normals;
  AmbiguityStats stats;
  std::size_t shared_vertices = 0;
  std::size_t top_first = 0;  // the vertices of slice `last`: [top_first, top_end)
  std::size_t top_end = 0;
  std::shared_ptr<SliceBuffers> slice_buffers;  // the extractor's, for recycling
};

// Told by extract_layers after each cube layer is triangulated, with what it has made so far
// (every vertex and triangle of that layer's cubes exists then; the arrays may move later).
class LayerObserver {
 public:
  // `layer`: the cube layer just done (extract_layers' numbering); `cubes`: the records of
  // every boundary cube so far, its own last.
  virtual void layer_done(std::int64_t layer, const TriangleMesh& mesh,
                          std::span<const BoundaryCube> cubes) = 0;

 protected:
  ~LayerObserver() = default;
};

// Cube layers extract_isosurface sweeps for these options (0 when there is no cube).
std::int64_t cube_layer_count(const Volume& volume, float iso, const ExtractOptions& options);

// Extracts one piece with its cube records (and its ambiguity counts when options.stats is
// set; the piece holds them, *options.stats is not touched), on the calling thread
// (options.threads and .cubes are ignored). defer_normals: the mesh gets no normals but
// vertex_edges, so that a caller who keeps few of the vertices (type merging keeps half or
// fewer) computes only theirs, with deferred_vertex_normal, equal to extract_isosurface's.
// expected_vertices >= 0: the outputs are reserved for about that many vertices (a caller's
// estimate) instead of from a sample of the layers; the piece is the same either way.
// recycled: an earlier piece whose arrays the new one is written into (emptied, capacity
// kept: a caller extracting piece after piece maps their pages once); left moved-from.
// observer: told after each layer (a caller that works on layers as they are made reads
// them while they are in cache).
// Precondition: 0 <= first < last <= cube_layer_count(volume, iso, options).
SurfacePiece extract_layers(const Volume& volume, float iso, const ExtractOptions& options,
                            std::int64_t first, std::int64_t last, bool defer_normals = false,
                            double expected_vertices = -1.0, SurfacePiece* recycled = nullptr,
                            LayerObserver* observer = nullptr);

// The normal extract_isosurface gives the vertex whose SurfacePiece::vertex_edges entry is
// `edge` (close_borders as the piece was extracted with).
std::array<float, 3> deferred_vertex_normal(
    const Volume& volume, float iso, bool close_borders, std::uint64_t edge,
    const std::vector<std::array<float, 3>>& centroid_normals);

}  // namespace detail

}  // namespace typemerge::core
