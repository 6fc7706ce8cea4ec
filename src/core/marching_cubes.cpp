// extract_isosurface: streaming marching cubes over padded slices.
//
// The volume is swept one cube layer (two neighbouring slices) at a time, in the scan order of
// spec §1.5 (x fastest, then y, then z). Per layer, in explicit passes:
//   1. load the upper slice into a padded buffer and classify its samples (inside bytes and
//      the 4-bit code of every square, so a cube index is two loads and a shift);
//   2. create one surface vertex per cut lattice edge: the x- and y-edges of the upper slice
//      and the z-edges between the slices. Every cut edge is used by every cube around it, so
//      vertices are created edge by edge, not on demand, and their ids are stored in per-slice
//      arrays indexed like the samples — no hashing, memory = mesh + a few slices;
//   3. triangulate the boundary cubes from the case tables, deciding ambiguous faces.
// Only the lower slice's buffers are needed from the previous layer, so two slices are kept
// and swapped. A layer depends on nothing but its two slices, which is what a later parallel
// version needs: slabs of layers processed independently, their vertices on the shared slice
// matched by the deterministic edge order.
//
// Padding (close_borders): the sample grid is extended by one sample of value −∞ on every
// side. −∞ is outside for any iso and makes the interpolated vertex land on the inside end of
// the edge, which the edge margin moves kEdgeMargin outward: the cap lies on the border.
#include "core/marching_cubes.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/cube_tables.h"

namespace typemerge::core {

namespace detail {

bool face_joins_inside(float a, float b, float c, float d, float iso) {
  const double ia = double{a} - iso;
  const double ic = double{c} - iso;
  const double ob = double{b} - iso;
  const double od = double{d} - iso;
  return ia * ic >= ob * od;
}

}  // namespace detail

namespace {

using Index = std::int64_t;
using VertexId = std::uint32_t;

constexpr float kPadding = -std::numeric_limits<float>::infinity();

// One padded slice and the vertex ids of its in-plane edges. Entry x + width·y belongs to the
// sample (x, y), its x-edge (x,y)–(x+1,y), its y-edge (x,y)–(x,y+1) and its square
// (x,y)–(x+1,y+1). Ids are valid only on cut edges; nothing else is ever read.
struct Slice {
  std::vector<float> values;
  std::vector<std::uint8_t> inside;
  std::vector<std::uint8_t> square;  // bits 0..3 = inside of (x,y) (x+1,y) (x+1,y+1) (x,y+1)
  std::vector<VertexId> x_vertex;
  std::vector<VertexId> y_vertex;

  void resize(std::size_t n) {
    values.resize(n);
    inside.resize(n);
    square.resize(n);
    x_vertex.resize(n);
    y_vertex.resize(n);
  }
};

// Where the vertex of each local cube edge is stored, relative to the cube's entry: in which
// of the five id arrays of a layer, at which offset.
enum EdgeArray : int { kLowerX, kLowerY, kUpperX, kUpperY, kBetweenZ };

class Extractor {
 public:
  Extractor(const Volume& volume, float iso, const ExtractOptions& options)
      : volume_(volume), iso_(iso), options_(options) {
    pad_ = options.close_borders ? 1 : 0;
    const VolumeSize& s = volume.size();
    width_ = s.nx + 2 * pad_;
    height_ = s.ny + 2 * pad_;
    depth_ = s.nz + 2 * pad_;
    if (options.mode == ExtractOptions::Mode::consistent) {
      cases_ = kConsistentCases.cases.data();
      first_ = kConsistentCases.first.data();
      decided_faces_ = kConsistentCases.decided_faces.data();
    } else {
      cases_ = kClassicCases.cases.data();
      first_ = kClassicCases.first.data();
      decided_faces_ = kClassicCases.decided_faces.data();
    }
    for (int e = 0; e < kCubeEdgeCount; ++e) {
      const LatticeEdge& lattice = kCubeEdgeLattice[e];
      const auto& o = lattice.offset;
      edge_array_[e] = lattice.axis == 2 ? kBetweenZ
                       : o[2] == 0       ? (lattice.axis == 0 ? kLowerX : kLowerY)
                                         : (lattice.axis == 0 ? kUpperX : kUpperY);
      edge_offset_[e] = o[0] + width_ * o[1];
    }
  }

  TriangleMesh run() {
    if (options_.stats != nullptr) *options_.stats = {};
    if (options_.cubes != nullptr) options_.cubes->clear();
    if (volume_.size().voxels() == 0 || width_ < 2 || height_ < 2 || depth_ < 2) return {};
    const std::size_t n = static_cast<std::size_t>(width_ * height_);
    Slice lower;
    Slice upper;
    lower.resize(n);
    upper.resize(n);
    z_vertex_.resize(n);

    load_slice(0, lower);
    add_slice_vertices(0, lower);
    for (Index layer = 0; layer + 1 < depth_; ++layer) {
      load_slice(layer + 1, upper);
      add_slice_vertices(layer + 1, upper);
      add_layer_vertices(layer, lower, upper);
      add_cubes(layer, lower, upper);
      std::swap(lower, upper);
    }
    if (options_.stats != nullptr) *options_.stats = stats_;
    return std::move(mesh_);
  }

 private:
  // Pass 1: padded copy of slice pz (padded index), inside bytes, square codes.
  void load_slice(Index pz, Slice& slice) const {
    const VolumeSize& s = volume_.size();
    const Index k = pz - pad_;
    std::fill(slice.values.begin(), slice.values.end(), kPadding);
    if (k >= 0 && k < s.nz) {
      const float* samples = volume_.slice(k);
      for (Index j = 0; j < s.ny; ++j) {
        std::copy_n(samples + s.nx * j, s.nx, slice.values.begin() + (j + pad_) * width_ + pad_);
      }
    }
    const std::size_t n = slice.values.size();
    for (std::size_t i = 0; i < n; ++i) slice.inside[i] = slice.values[i] >= iso_ ? 1 : 0;
    const std::uint8_t* in = slice.inside.data();
    for (Index y = 0; y + 1 < height_; ++y) {
      const std::uint8_t* row = in + y * width_;
      const std::uint8_t* next = row + width_;
      std::uint8_t* out = slice.square.data() + y * width_;
      for (Index x = 0; x + 1 < width_; ++x) {
        out[x] =
            static_cast<std::uint8_t>(row[x] | row[x + 1] << 1 | next[x + 1] << 2 | next[x] << 3);
      }
    }
  }

  // Pass 2a: vertices on the cut x- and y-edges of slice pz.
  void add_slice_vertices(Index pz, Slice& slice) {
    const std::uint8_t* in = slice.inside.data();
    const float* v = slice.values.data();
    for (Index y = 0; y < height_; ++y) {
      for (Index x = 0; x + 1 < width_; ++x) {
        const Index i = x + width_ * y;
        if (in[i] != in[i + 1]) slice.x_vertex[i] = add_edge_vertex(x, y, pz, 0, v[i], v[i + 1]);
      }
    }
    for (Index y = 0; y + 1 < height_; ++y) {
      for (Index x = 0; x < width_; ++x) {
        const Index i = x + width_ * y;
        if (in[i] != in[i + width_]) {
          slice.y_vertex[i] = add_edge_vertex(x, y, pz, 1, v[i], v[i + width_]);
        }
      }
    }
  }

  // Pass 2b: vertices on the cut z-edges between slice pz and pz + 1.
  void add_layer_vertices(Index pz, const Slice& lower, const Slice& upper) {
    for (Index y = 0; y < height_; ++y) {
      for (Index x = 0; x < width_; ++x) {
        const Index i = x + width_ * y;
        if (lower.inside[i] != upper.inside[i]) {
          z_vertex_[i] = add_edge_vertex(x, y, pz, 2, lower.values[i], upper.values[i]);
        }
      }
    }
  }

  // Pass 3: the boundary cubes of the layer between the two slices.
  void add_cubes(Index layer, const Slice& lower, const Slice& upper) {
    const std::uint8_t* lower_square = lower.square.data();
    const std::uint8_t* upper_square = upper.square.data();
    const std::array<const VertexId*, 5> ids = {lower.x_vertex.data(), lower.y_vertex.data(),
                                                upper.x_vertex.data(), upper.y_vertex.data(),
                                                z_vertex_.data()};
    for (Index y = 0; y + 1 < height_; ++y) {
      for (Index x = 0; x + 1 < width_; ++x) {
        const Index i = x + width_ * y;
        const unsigned c = static_cast<unsigned>(lower_square[i] | upper_square[i] << 4);
        if (c == 0 || c == 255) continue;
        if (options_.cubes != nullptr) {
          options_.cubes->push_back({static_cast<std::int32_t>(x - pad_),
                                     static_cast<std::int32_t>(y - pad_),
                                     static_cast<std::int32_t>(layer - pad_),
                                     static_cast<std::uint8_t>(c),
                                     static_cast<std::uint32_t>(mesh_.triangles.size())});
        }
        add_cube(c, i, ids, lower, upper);
      }
    }
  }

  void add_cube(unsigned c, Index i, const std::array<const VertexId*, 5>& ids, const Slice& lower,
                const Slice& upper) {
    unsigned entry = first_[c];
    const unsigned decided = decided_faces_[c];
    const unsigned ambiguous = kCubeAmbiguousFaces[c];
    if (decided != 0) entry += decide_faces(c, decided, i, lower, upper);
    if (options_.stats != nullptr) {
      ++stats_.boundary_cubes;
      ++stats_.cubes_with_ambiguous_faces[std::popcount(ambiguous)];
      if (ambiguous != 0) {
        stats_.joined_faces += std::popcount(decide_faces(c, ambiguous, i, lower, upper));
      }
    }

    const CubeCase& cube_case = cases_[entry];
    std::array<VertexId, kFirstCentroid + kMaxCaseCentroids> local{};
    for (unsigned cut = kCubeCutEdges[c]; cut != 0; cut &= cut - 1) {
      const int e = std::countr_zero(cut);
      local[e] = ids[edge_array_[e]][i + edge_offset_[e]];
    }
    for (int k = 0; k < cube_case.centroid_count; ++k) {
      local[kFirstCentroid + k] = add_centroid(cube_case.centroid_edges[k], local);
      if (options_.stats != nullptr) ++stats_.centroid_vertices;
    }
    for (int t = 0; t < cube_case.triangle_count; ++t) {
      const auto& tri = cube_case.triangles[t];
      mesh_.triangles.push_back({local[tri[0]], local[tri[1]], local[tri[2]]});
    }
  }

  // Decisions on the faces in `faces` (a subset of c's ambiguous faces), packed in face order:
  // bit k = the k-th face of `faces` joins its inside corners.
  unsigned decide_faces(unsigned c, unsigned faces, Index i, const Slice& lower,
                        const Slice& upper) const {
    float value[kCubeVertexCount];
    for (int v = 0; v < kCubeVertexCount; ++v) {
      const auto& o = kCubeVertexOffset[v];
      value[v] = (o[2] == 0 ? lower : upper).values[i + o[0] + width_ * o[1]];
    }
    unsigned decisions = 0;
    int k = 0;
    for (unsigned rest = faces; rest != 0; rest &= rest - 1, ++k) {
      const auto& f = kCubeFaceVertices[std::countr_zero(rest)];
      // Hand the decider the inside diagonal first; which corner starts does not matter.
      const bool first_inside = ((c >> f[0]) & 1u) != 0;
      const int a = first_inside ? 0 : 1;
      if (detail::face_joins_inside(value[f[a]], value[f[a + 1]], value[f[(a + 2) % 4]],
                                    value[f[(a + 3) % 4]], iso_)) {
        decisions |= 1u << k;
      }
    }
    return decisions;
  }

  // The vertex on the lattice edge from padded sample (x, y, z) one step along `axis`, whose
  // values are `lo` there and `hi` at the other end (exactly one of them inside).
  VertexId add_edge_vertex(Index x, Index y, Index z, int axis, float lo, float hi) {
    const bool lo_inside = lo >= iso_;
    const float in = lo_inside ? lo : hi;
    const float out = lo_inside ? hi : lo;
    // Fraction of the way from the inside end to the outside end; in [0, 1) since
    // out < iso <= in, and 0 when out is the −∞ padding. The margin keeps the vertex off both
    // samples (the tie rule: a sample equal to iso is inside, its vertices sit just outside).
    double t = (double{iso_} - in) / (double{out} - in);
    t = std::clamp(t, double{kEdgeMargin}, 1.0 - double{kEdgeMargin});
    const double s = lo_inside ? t : 1.0 - t;  // from the lower end

    std::array<Index, 3> p_lo = {x - pad_, y - pad_, z - pad_};
    std::array<Index, 3> p_hi = p_lo;
    ++p_hi[axis];
    std::array<float, 3> position = {static_cast<float>(p_lo[0]), static_cast<float>(p_lo[1]),
                                     static_cast<float>(p_lo[2])};
    position[axis] = static_cast<float>(static_cast<double>(p_lo[axis]) + s);

    // Outward = toward lower values = −gradient; on a cap (the outside end is padding) the
    // border normal, which is also the fallback where the gradient vanishes.
    const std::array<Index, 3>& p_in = lo_inside ? p_lo : p_hi;
    const std::array<Index, 3>& p_out = lo_inside ? p_hi : p_lo;
    std::array<double, 3> normal{0, 0, 0};
    if (is_sample(p_out)) {
      const std::array<double, 3> g_in = gradient(p_in);
      const std::array<double, 3> g_out = gradient(p_out);
      for (int a = 0; a < 3; ++a) normal[a] = -((1.0 - t) * g_in[a] + t * g_out[a]);
    }
    double length =
        std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    if (!(length > 0.0)) {
      normal = {0, 0, 0};
      normal[axis] = lo_inside ? 1.0 : -1.0;
      length = 1.0;
    }

    mesh_.positions.push_back(position);
    mesh_.normals.push_back({static_cast<float>(normal[0] / length),
                             static_cast<float>(normal[1] / length),
                             static_cast<float>(normal[2] / length)});
    assert(mesh_.positions.size() <= std::numeric_limits<VertexId>::max());
    return static_cast<VertexId>(mesh_.positions.size() - 1);
  }

  // A loop's centre vertex: the mean of its vertices, with their mean normal.
  VertexId add_centroid(unsigned edges,
                        const std::array<VertexId, kFirstCentroid + kMaxCaseCentroids>& local) {
    std::array<double, 3> position{0, 0, 0};
    std::array<double, 3> normal{0, 0, 0};
    int count = 0;
    for (unsigned rest = edges; rest != 0; rest &= rest - 1, ++count) {
      const VertexId v = local[std::countr_zero(rest)];
      for (int a = 0; a < 3; ++a) {
        position[a] += mesh_.positions[v][a];
        normal[a] += mesh_.normals[v][a];
      }
    }
    const double length =
        std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    const double scale = length > 0.0 ? 1.0 / length : 0.0;
    mesh_.positions.push_back({static_cast<float>(position[0] / count),
                               static_cast<float>(position[1] / count),
                               static_cast<float>(position[2] / count)});
    mesh_.normals.push_back({static_cast<float>(normal[0] * scale),
                             static_cast<float>(normal[1] * scale),
                             static_cast<float>(normal[2] * scale)});
    return static_cast<VertexId>(mesh_.positions.size() - 1);
  }

  bool is_sample(const std::array<Index, 3>& p) const {
    const VolumeSize& s = volume_.size();
    return p[0] >= 0 && p[0] < s.nx && p[1] >= 0 && p[1] < s.ny && p[2] >= 0 && p[2] < s.nz;
  }

  // Central differences inside the volume, one-sided at its border (per index step).
  std::array<double, 3> gradient(const std::array<Index, 3>& p) const {
    const std::array<Index, 3> n = {volume_.size().nx, volume_.size().ny, volume_.size().nz};
    std::array<double, 3> g{0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      std::array<Index, 3> lo = p;
      std::array<Index, 3> hi = p;
      lo[a] = std::max<Index>(p[a] - 1, 0);
      hi[a] = std::min<Index>(p[a] + 1, n[a] - 1);
      if (hi[a] == lo[a]) continue;
      g[a] = (double{volume_.at(hi[0], hi[1], hi[2])} - volume_.at(lo[0], lo[1], lo[2])) /
             static_cast<double>(hi[a] - lo[a]);
    }
    return g;
  }

  const Volume& volume_;
  float iso_;
  ExtractOptions options_;
  Index pad_ = 0;
  Index width_ = 0;   // padded samples along x
  Index height_ = 0;  // padded samples along y
  Index depth_ = 0;   // padded slices
  const CubeCase* cases_ = nullptr;
  const std::uint16_t* first_ = nullptr;
  const std::uint8_t* decided_faces_ = nullptr;
  std::array<int, kCubeEdgeCount> edge_array_{};
  std::array<Index, kCubeEdgeCount> edge_offset_{};
  std::vector<VertexId> z_vertex_;
  TriangleMesh mesh_;
  AmbiguityStats stats_;
};

}  // namespace

TriangleMesh extract_isosurface(const Volume& volume, float iso, const ExtractOptions& options) {
  assert(volume.samples().size() == static_cast<std::size_t>(volume.size().voxels()));
  return Extractor(volume, iso, options).run();
}

}  // namespace typemerge::core
