// extract_isosurface: streaming marching cubes over padded slices.
//
// The volume is swept one cube layer (two neighbouring slices) at a time, in the scan order of
// spec §1.5 (x fastest, then y, then z). Per layer, in explicit passes:
//   1. load the upper slice into a padded buffer and classify its samples (inside bytes), and
//      trim every row as flying edges does (Schroeder et al. 2015): the first and last cut
//      x-edge of the row and the state at its two ends. Outside its trim a row is constant, so
//      every later pass scans, per row, only the x range where some sample it compares can
//      differ — on CT most rows have no crossing at all and cost one classification;
//   2. create one surface vertex per cut lattice edge: the x- and y-edges of the upper slice
//      and the z-edges between the slices. Every cut edge is used by every cube around it, so
//      vertices are created edge by edge, not on demand, and their ids are stored in per-slice
//      arrays indexed like the samples — no hashing, memory = mesh + a few slices;
//   3. triangulate the boundary cubes from the case tables, deciding ambiguous faces.
// Only the lower slice's buffers are needed from the previous layer, so two slices are kept
// and swapped.
//
// Threads (ExtractOptions::threads): a layer depends on nothing but its two slices, so the
// layers are cut into slabs that are extracted independently, each into its own mesh, and
// concatenated in slab order. The slice shared by two slabs is classified by both, but its
// vertices are emitted only by the lower slab: the upper slab numbers them 0..k−1 in the
// deterministic edge order, which is the order in which the lower slab created them, so
// the upper slab's references are renumbered onto the lower slab's range. The result —
// vertex order, triangles, cube records, statistics — is byte for byte the serial one, for
// any thread and slab count. std::thread rather than TBB or OpenMP: the core is std-only.
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
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/cube_tables.h"
#include "core/huge_pages.h"
#include "core/page_release.h"
#include "core/parallel.h"

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

bool is_sample(const Volume& volume, const std::array<Index, 3>& p) {
  const VolumeSize& s = volume.size();
  return p[0] >= 0 && p[0] < s.nx && p[1] >= 0 && p[1] < s.ny && p[2] >= 0 && p[2] < s.nz;
}

// Central differences inside the volume, one-sided at its border (per index step). Samples
// with both neighbours along every axis read them directly (the same arithmetic): the
// clamped lookups were most of a vertex's cost.
std::array<double, 3> gradient(const Volume& volume, const std::array<Index, 3>& p) {
  const std::array<Index, 3> n = {volume.size().nx, volume.size().ny, volume.size().nz};
  if (p[0] > 0 && p[0] + 1 < n[0] && p[1] > 0 && p[1] + 1 < n[1] && p[2] > 0 && p[2] + 1 < n[2]) {
    const Index row = n[0];
    const Index slice = n[0] * n[1];
    // Either storage: an int16 sample converts to the double of the float it would be.
    return volume.visit([&](const auto* samples) -> std::array<double, 3> {
      const auto* c = samples + p[0] + row * p[1] + slice * p[2];
      return {(double(c[1]) - double(c[-1])) / 2.0, (double(c[row]) - double(c[-row])) / 2.0,
              (double(c[slice]) - double(c[-slice])) / 2.0};
    });
  }
  std::array<double, 3> g{0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    std::array<Index, 3> lo = p;
    std::array<Index, 3> hi = p;
    lo[a] = std::max<Index>(p[a] - 1, 0);
    hi[a] = std::min<Index>(p[a] + 1, n[a] - 1);
    if (hi[a] == lo[a]) continue;
    g[a] = (double{volume.at(hi[0], hi[1], hi[2])} - volume.at(lo[0], lo[1], lo[2])) /
           static_cast<double>(hi[a] - lo[a]);
  }
  return g;
}

// Fraction of the way from the inside end to the outside end of a cut edge whose values are
// `in` (>= iso) and `out` (< iso); in [0, 1) since out < iso <= in, and 0 when out is the −∞
// padding. The margin keeps the vertex off both samples (the tie rule: a sample equal to iso
// is inside, its vertices sit just outside).
double edge_fraction(float in, float out, float iso) {
  const double t = (double{iso} - in) / (double{out} - in);
  return std::clamp(t, double{kEdgeMargin}, 1.0 - double{kEdgeMargin});
}

// The unit normal of the vertex at fraction t from the inside end p_in of a cut lattice edge
// (p_out its outside end, one step along `axis`): outward = toward lower values =
// −gradient; on a cap (the outside end is padding) the border normal, which is also the
// fallback where the gradient vanishes.
std::array<float, 3> edge_normal(const Volume& volume, const std::array<Index, 3>& p_in,
                                 const std::array<Index, 3>& p_out, int axis, double t) {
  std::array<double, 3> normal{0, 0, 0};
  if (is_sample(volume, p_out)) {
    const std::array<double, 3> g_in = gradient(volume, p_in);
    const std::array<double, 3> g_out = gradient(volume, p_out);
    for (int a = 0; a < 3; ++a) normal[a] = -((1.0 - t) * g_in[a] + t * g_out[a]);
  }
  double length = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
  if (!(length > 0.0)) {
    normal = {0, 0, 0};
    normal[axis] = p_out[axis] > p_in[axis] ? 1.0 : -1.0;
    length = 1.0;
  }
  return {static_cast<float>(normal[0] / length), static_cast<float>(normal[1] / length),
          static_cast<float>(normal[2] / length)};
}

// A deferred vertex's lattice edge (detail::SurfacePiece::vertex_edges): its lower end in
// the padded grid, linearly, times 4, plus its axis; a loop's centre vertex is 4k + 3, k its
// index in centroid_normals.
constexpr std::uint64_t kCentroidEdge = 3;

// Ambiguous faces per cube code (a table: without -mpopcnt, std::popcount is a library call).
constexpr std::array<std::uint8_t, 256> kAmbiguousFaceCount = [] {
  std::array<std::uint8_t, 256> count{};
  for (unsigned c = 0; c < 256; ++c) {
    count[c] = static_cast<std::uint8_t>(std::popcount(kCubeAmbiguousFaces[c]));
  }
  return count;
}();

// Word-at-a-time scans, 8 bytes per step: inside a body most of a trimmed row is inside, where
// no edge is cut and no cube is a boundary cube, and testing those bytes one by one was most
// of the extraction time at skin thresholds (abdomen, −500 HU). The first byte found is the
// lowest-addressed one (little-endian; other byte orders scan byte by byte), so vertices and
// cubes are still visited in increasing x.
constexpr bool kWordScan = std::endian::native == std::endian::little;

std::uint64_t load_word(const std::uint8_t* p) {
  std::uint64_t w;
  std::memcpy(&w, p, sizeof w);
  return w;
}

// First x in [x, end) with a[x] != b[x], or end.
Index next_difference(const std::uint8_t* a, const std::uint8_t* b, Index x, Index end) {
  if constexpr (kWordScan) {
    for (; x + 8 <= end; x += 8) {
      if (const std::uint64_t d = load_word(a + x) ^ load_word(b + x); d != 0) {
        return x + std::countr_zero(d) / 8;
      }
    }
  }
  while (x < end && a[x] == b[x]) ++x;
  return x;
}

// Last x in [begin, end) with a[x] != b[x], or begin − 1.
Index last_difference(const std::uint8_t* a, const std::uint8_t* b, Index begin, Index end) {
  if constexpr (kWordScan) {
    for (; end - 8 >= begin; end -= 8) {
      if (const std::uint64_t d = load_word(a + end - 8) ^ load_word(b + end - 8); d != 0) {
        return end - 8 + (63 - std::countl_zero(d)) / 8;
      }
    }
  }
  while (end > begin && a[end - 1] == b[end - 1]) --end;
  return end - 1;
}

// First x in [x, end) whose cube code is neither 0 (outside) nor 255 (inside), or end.
Index next_boundary_code(const std::uint8_t* codes, Index x, Index end) {
  if constexpr (kWordScan) {
    for (; x + 8 <= end; x += 8) {
      const std::uint64_t w = load_word(codes + x);
      // Each byte's top bit spread over the byte: equal to the byte exactly when it is 0 or 255.
      const std::uint64_t spread = ((w >> 7) & 0x0101010101010101u) * 0xFFu;
      if (const std::uint64_t d = w ^ spread; d != 0) return x + std::countr_zero(d) / 8;
    }
  }
  while (x < end && (codes[x] == 0 || codes[x] == 255)) ++x;
  return x;
}

// Inside flags (1: value >= iso, the tie rule) of n samples: a plain loop the compiler
// vectorises.
void classify_samples(const float* values, std::size_t n, float iso, std::uint8_t* inside) {
  std::transform(values, values + n, inside, [iso](float f) { return std::uint8_t{f >= iso}; });
}

// The same for int16 samples: v >= iso exactly when v >= ⌈iso⌉ (v an integer), compared as
// int16 so that the loop vectorises eight samples a step or more (none is inside when ⌈iso⌉
// is beyond int16).
void classify_samples(const std::int16_t* values, std::size_t n, float iso,
                      std::uint8_t* inside) {
  const std::int32_t threshold = int16_threshold(iso);
  if (threshold > std::numeric_limits<std::int16_t>::max()) {
    std::fill_n(inside, n, std::uint8_t{0});
    return;
  }
  const auto t = static_cast<std::int16_t>(threshold);
  std::transform(values, values + n, inside, [t](std::int16_t v) { return std::uint8_t{v >= t}; });
}

// Positions i < n where a[i] != b[i] (inside flags, 0 or 1): a plain loop the compiler
// vectorises.
std::size_t count_differences(const std::uint8_t* a, const std::uint8_t* b, std::size_t n) {
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) count += a[i] ^ b[i];
  return count;
}

// One padded slice and the vertex ids of its in-plane edges. Entry x + width·y belongs to the
// sample (x, y), its x-edge (x,y)–(x+1,y) and its y-edge (x,y)–(x,y+1). Ids are valid only on
// cut edges; nothing else is ever read.
//
// Row trim of row y: samples x <= first_cut[y] are all `left[y]`, samples x > last_cut[y] are
// all `right[y]` (the cut x-edges lie in [first_cut, last_cut]); a row without a cut has
// first_cut = width − 1 and last_cut = −1, and left = right.
// Arrays are views into the extractor's SliceBuffers, not initialised: a slice's samples (but
// a padding slice's, all kPadding, which are not stored) and flags are all written by
// load_slice, and vertex ids (of slices and z-edges) are read only on cut edges, where they
// were written.
template <typename T>
class Scratch {
 public:
  // Bytes place() takes for n elements: theirs, rounded up to a cache line.
  static constexpr std::size_t bytes(std::size_t n) {
    constexpr std::size_t kLine = 64;
    return (n * sizeof(T) + kLine - 1) / kLine * kLine;
  }
  // Views n elements at `data`; returns the byte just past them (bytes(n) on).
  std::byte* place(std::byte* data, std::size_t n) {
    data_ = reinterpret_cast<T*>(data);
    size_ = n;
    return data + bytes(n);
  }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T* begin() { return data_; }
  T* end() { return data_ + size_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

struct Slice {
  // The padded samples as floats; for an int16 volume's slice only `int16` (its samples,
  // unpadded), read through Extractor::value.
  Scratch<float> values;
  const std::int16_t* int16 = nullptr;
  bool padding = false;  // a padding slice (close_borders): every sample kPadding, `values` unset
  Scratch<std::uint8_t> inside;
  Scratch<VertexId> x_vertex;
  Scratch<VertexId> y_vertex;
  std::vector<std::int32_t> first_cut;
  std::vector<std::int32_t> last_cut;
  std::vector<std::uint8_t> left;
  std::vector<std::uint8_t> right;

  // Bytes place() takes for slices of n samples, without `values`.
  static std::size_t bytes(std::size_t n) {
    return 2 * Scratch<VertexId>::bytes(n) + Scratch<std::uint8_t>::bytes(n);
  }

  // Views its arrays but `values` from `block` on; returns the byte just past them.
  std::byte* place(std::byte* block, std::size_t n, std::size_t rows) {
    block = x_vertex.place(block, n);
    block = y_vertex.place(block, n);
    block = inside.place(block, n);
    first_cut.resize(rows);
    last_cut.resize(rows);
    left.resize(rows);
    right.resize(rows);
    return block;
  }
};

// Range of x to scan, inclusive, where sample x of one trimmed row can differ from sample x of
// another (a, b) — or, for cubes, where some of the rows' samples x and x + 1 can differ
// (`span` = 1). Empty when first > last.
struct XRange {
  Index first;
  Index last;
};

// Where the vertex of each local cube edge is stored, relative to the cube's entry: in which
// of the five id arrays of a layer, at which offset.
enum EdgeArray : int { kLowerX, kLowerY, kUpperX, kUpperY, kBetweenZ };

class Extractor {
 public:
  Extractor(const Volume& volume, float iso, const ExtractOptions& options,
            bool defer_normals = false)
      : volume_(volume),
        iso_(iso),
        options_(options),
        defer_normals_(defer_normals),
        normals_(options.vertex_normals && !defer_normals) {
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

  // Cube layers (two neighbouring padded slices) in the volume; 0 when there is no cube.
  Index layers() const {
    if (volume_.size().voxels() == 0 || width_ < 2 || height_ < 2 || depth_ < 2) return 0;
    return depth_ - 1;
  }

  // Extracts layers [first, last). When first > 0 the vertices of slice `first` belong to the
  // slab below: they get the local ids 0..shared_vertices_ − 1 and are not part of the output.
  void run(Index first, Index last, double expected_vertices = -1.0,
           detail::LayerObserver* observer = nullptr) {
    const std::size_t n = static_cast<std::size_t>(width_ * height_);
    const auto rows = static_cast<std::size_t>(height_);
    if (!buffers_) buffers_ = std::make_shared<detail::SliceBuffers>();
    // The float samples (a float volume's only: an int16 volume's are read where they are
    // stored, and padding slices store none) last, after the ids and flags every volume writes.
    const bool floats = !volume_.holds_int16();
    const std::size_t value_bytes = floats ? 2 * Scratch<float>::bytes(n) : 0;
    std::byte* block =
        buffers_->reserve(Scratch<VertexId>::bytes(n) + 2 * Slice::bytes(n) + value_bytes);
    Slice lower;
    Slice upper;
    block = z_vertex_.place(block, n);
    block = lower.place(block, n, rows);
    block = upper.place(block, n, rows);
    if (floats) upper.values.place(lower.values.place(block, n), n);
    codes_.resize(static_cast<std::size_t>(width_));

    reserve_outputs(first, last, expected_vertices);
    load_slice(first, lower);
    add_slice_vertices(first, lower);
    shared_vertices_ = first > 0 ? mesh_.positions.size() : 0;
    for (Index layer = first; layer < last; ++layer) {
      load_slice(layer + 1, upper);
      last_slice_first_vertex_ = mesh_.positions.size();
      add_slice_vertices(layer + 1, upper);
      last_slice_end_vertex_ = mesh_.positions.size();
      add_layer_vertices(layer, lower, upper);
      add_cubes(layer, lower, upper);
      if (observer != nullptr) observer->layer_done(layer, mesh_, cubes_);
      std::swap(lower, upper);
    }
  }

  // Writes its outputs into an earlier piece's arrays (emptied here, their capacity kept).
  void reuse(detail::SurfacePiece&& old) {
    const auto take = [](auto& into, auto& from) {
      into = std::move(from);
      into.clear();
    };
    take(mesh_.positions, old.mesh.positions);
    take(mesh_.normals, old.mesh.normals);
    take(mesh_.triangles, old.mesh.triangles);
    take(vertex_edges_, old.vertex_edges);
    take(centroid_normals_, old.centroid_normals);
    take(cubes_, old.cubes);
    buffers_ = std::move(old.slice_buffers);
  }

  TriangleMesh& mesh() { return mesh_; }
  std::vector<std::uint64_t>& vertex_edges() { return vertex_edges_; }
  std::vector<std::array<float, 3>>& centroid_normals() { return centroid_normals_; }
  const AmbiguityStats& stats() const { return stats_; }
  std::vector<BoundaryCube>& cubes() { return cubes_; }
  std::shared_ptr<detail::SliceBuffers>& slice_buffers() { return buffers_; }
  std::size_t shared_vertices() const { return shared_vertices_; }
  std::size_t last_slice_first_vertex() const { return last_slice_first_vertex_; }
  std::size_t last_slice_end_vertex() const { return last_slice_end_vertex_; }

 private:
  // Reserves the outputs of layers [first, last) from a sample of them, so that the mesh is
  // written once where it stays: grown by doubling it was copied and touched twice its pages
  // (abdomen, 1 thread: marching cubes 9–20 % faster, peak memory 40 → 27 MiB at 300 HU and
  // 118 → 59 MiB at −500). Sampled layers are measured — cut edges of the layer's upper slice
  // (the first layer's lower slice too) and between its slices, one vertex each, the caps
  // where a slice is the padding — on the unpadded samples (the caps on the x and y borders
  // are left out); a mesh has about two triangles per vertex, a boundary cube about one
  // vertex. What the sample misses, the usual doubling makes up; what it overestimates costs
  // address space, not memory (pages are touched only when written). Sampling classifies about
  // a quarter of the slices again (`perf`: 1–2 % of the extraction time).
  // With an estimate (expected >= 0) the sampling is skipped.
  void reserve_outputs(Index first, Index last, double expected) {
    const auto reserve = [](auto& v, double count) {
      try {
        detail::reserve_on_huge_pages(v, static_cast<std::size_t>(1.25 * count) + 64);
      } catch (const std::bad_alloc&) {
      } catch (const std::length_error&) {
      }
    };
    const auto reserve_all = [&](double vertices) {
      reserve(mesh_.positions, vertices);
      if (defer_normals_) reserve(vertex_edges_, vertices);
      if (normals_) reserve(mesh_.normals, vertices);
      reserve(mesh_.triangles, 2.0 * vertices);
      if (options_.cubes != nullptr) reserve(cubes_, vertices);
    };
    if (expected >= 0.0) {
      reserve_all(expected);
      return;
    }
    constexpr Index kSampleStride = 8;
    const VolumeSize& s = volume_.size();
    const auto n = static_cast<std::size_t>(s.nx * s.ny);
    const auto nx = static_cast<std::size_t>(s.nx);
    std::vector<std::uint8_t> lower(n);
    std::vector<std::uint8_t> upper(n);
    // Inside flags of padded slice pz; false for a padding slice (all outside).
    auto classify = [&](Index pz, std::vector<std::uint8_t>& in) {
      const Index k = pz - pad_;
      if (k < 0 || k >= s.nz) return false;
      volume_.visit([&](const auto* samples) {
        classify_samples(samples + static_cast<std::size_t>(k) * n, n, iso_, in.data());
      });
      return true;
    };
    auto in_plane = [&](const std::vector<std::uint8_t>& in) {
      return count_differences(in.data(), in.data() + 1, n - 1) +
             count_differences(in.data(), in.data() + nx, n - nx);
    };
    const std::vector<std::uint8_t> none(n, 0);
    double vertices = 0.0;
    if (classify(first, upper)) vertices += static_cast<double>(in_plane(upper));
    // The first and the last layer stand for themselves (they hold the caps where the volume
    // ends), every sampled layer between them for up to kSampleStride layers.
    for (Index layer = first; layer < last;) {
      const Index next = layer == first || layer + 1 == last
                             ? layer + 1
                             : std::min(layer + kSampleStride, last - 1);
      const bool has_lower = classify(layer, lower);
      const bool has_upper = classify(layer + 1, upper);
      const std::size_t z_cuts = count_differences((has_lower ? lower : none).data(),
                                                   (has_upper ? upper : none).data(), n);
      const std::size_t cuts = (has_upper ? in_plane(upper) : 0) + z_cuts;
      vertices += static_cast<double>(cuts) * static_cast<double>(next - layer);
      layer = next;
    }
    // A sample can overestimate (a dense sampled layer among sparse ones, by up to
    // kSampleStride×): if the address space is refused, the outputs grow as before.
    reserve_all(vertices);
  }

  // Sample (x, y) (padded) of a slice: an int16 sample becomes the float of the same integer
  // here, as a float volume's sample is copied, so both storages give the same surface bit for
  // bit (and the int16 samples are not copied for the few at cut edges that are read).
  float value(const Slice& slice, Index x, Index y) const {
    if (slice.int16 == nullptr) {
      return slice.padding ? kPadding : slice.values[static_cast<std::size_t>(x + width_ * y)];
    }
    const VolumeSize& s = volume_.size();
    const Index vx = x - pad_;
    const Index vy = y - pad_;
    if (vx < 0 || vy < 0 || vx >= s.nx || vy >= s.ny) return kPadding;
    return static_cast<float>(slice.int16[vx + s.nx * vy]);
  }

  // Pass 1: slice pz's samples (a padded copy of a float volume's), inside bytes, row trims.
  void load_slice(Index pz, Slice& slice) const {
    const VolumeSize& s = volume_.size();
    const Index k = pz - pad_;
    slice.int16 = nullptr;
    slice.padding = k < 0 || k >= s.nz;
    if (!slice.padding) {
      // The samples are classified where they are stored (int16 ones in int16, twice as many
      // a vector step).
      const std::uint8_t padding_inside = kPadding >= iso_ ? 1 : 0;
      if (pad_ != 0) {
        std::fill_n(slice.inside.begin(), width_, padding_inside);
        std::fill_n(slice.inside.end() - width_, width_, padding_inside);
      }
      volume_.visit([&](const auto* all) {
        const auto* samples = all + s.nx * s.ny * k;
        using Sample = std::remove_cv_t<std::remove_pointer_t<decltype(all)>>;
        constexpr bool kCopy = std::is_same_v<Sample, float>;
        if constexpr (kCopy) {
          if (pad_ != 0) {
            std::fill_n(slice.values.begin(), width_, kPadding);
            std::fill_n(slice.values.end() - width_, width_, kPadding);
          }
        } else {
          slice.int16 = samples;
        }
        for (Index j = 0; j < s.ny; ++j) {
          std::uint8_t* in = slice.inside.data() + (j + pad_) * width_;
          if (pad_ != 0) in[0] = in[width_ - 1] = padding_inside;
          if constexpr (kCopy) {
            float* row = slice.values.data() + (j + pad_) * width_;
            if (pad_ != 0) row[0] = row[width_ - 1] = kPadding;
            std::copy_n(samples + s.nx * j, s.nx, row + pad_);
          }
          classify_samples(samples + s.nx * j, static_cast<std::size_t>(s.nx), iso_, in + pad_);
        }
      });
    } else {
      std::fill(slice.inside.begin(), slice.inside.end(),
                std::uint8_t{kPadding >= iso_ ? std::uint8_t{1} : std::uint8_t{0}});
    }
    for (Index y = 0; y < height_; ++y) {
      std::uint8_t* in = slice.inside.data() + y * width_;
      const auto row = static_cast<std::size_t>(y);
      slice.left[row] = in[0];
      slice.right[row] = in[width_ - 1];
      // No flag (0 or 1) other than the first's: the row has no cut x-edge (memchr scans a
      // vector a step, fewer instructions than counting the flags).
      if (std::memchr(in, in[0] ^ 1, static_cast<std::size_t>(width_)) == nullptr) {
        slice.first_cut[row] = static_cast<std::int32_t>(width_ - 1);
        slice.last_cut[row] = -1;
        continue;
      }
      // The row has a cut x-edge: both scans find one.
      slice.first_cut[row] = static_cast<std::int32_t>(next_difference(in, in + 1, 0, width_ - 1));
      slice.last_cut[row] = static_cast<std::int32_t>(last_difference(in, in + 1, 0, width_ - 1));
    }
  }

  // Samples where row ya of slice a and row yb of slice b can differ.
  XRange pair_range(const Slice& a, Index ya, const Slice& b, Index yb) const {
    const auto ra = static_cast<std::size_t>(ya);
    const auto rb = static_cast<std::size_t>(yb);
    const Index first = a.left[ra] == b.left[rb]
                            ? Index{std::min(a.first_cut[ra], b.first_cut[rb])} + 1
                            : 0;
    const Index last = a.right[ra] == b.right[rb]
                           ? Index{std::max(a.last_cut[ra], b.last_cut[rb])}
                           : width_ - 1;
    return {first, last};
  }

  // Cubes (x from 0 to width − 2) of the cube row y between `lower` and `upper` whose eight
  // corners can differ.
  XRange cube_range(const Slice& lower, const Slice& upper, Index y) const {
    const auto r0 = static_cast<std::size_t>(y);
    const auto r1 = r0 + 1;
    const std::uint8_t l = lower.left[r0];
    const std::uint8_t r = lower.right[r0];
    const bool same_left = lower.left[r1] == l && upper.left[r0] == l && upper.left[r1] == l;
    const bool same_right = lower.right[r1] == r && upper.right[r0] == r && upper.right[r1] == r;
    const Index first =
        same_left ? Index{std::min({lower.first_cut[r0], lower.first_cut[r1], upper.first_cut[r0],
                                    upper.first_cut[r1]})}
                  : 0;
    const Index last =
        same_right ? std::min<Index>(std::max({lower.last_cut[r0], lower.last_cut[r1],
                                               upper.last_cut[r0], upper.last_cut[r1]}),
                                     width_ - 2)
                   : width_ - 2;
    return {first, last};
  }

  // Pass 2a: vertices on the cut x- and y-edges of slice pz.
  void add_slice_vertices(Index pz, Slice& slice) {
    const std::uint8_t* in = slice.inside.data();
    for (Index y = 0; y < height_; ++y) {
      const auto row = static_cast<std::size_t>(y);
      const std::uint8_t* r = in + width_ * y;
      const Index end = Index{slice.last_cut[row]} + 1;
      for (Index x = next_difference(r, r + 1, slice.first_cut[row], end); x < end;
           x = next_difference(r, r + 1, x + 1, end)) {
        const Index i = x + width_ * y;
        slice.x_vertex[i] =
            add_edge_vertex(x, y, pz, 0, value(slice, x, y), value(slice, x + 1, y));
      }
    }
    for (Index y = 0; y + 1 < height_; ++y) {
      const XRange range = pair_range(slice, y, slice, y + 1);
      const std::uint8_t* r = in + width_ * y;
      const Index end = range.last + 1;
      for (Index x = next_difference(r, r + width_, range.first, end); x < end;
           x = next_difference(r, r + width_, x + 1, end)) {
        const Index i = x + width_ * y;
        slice.y_vertex[i] =
            add_edge_vertex(x, y, pz, 1, value(slice, x, y), value(slice, x, y + 1));
      }
    }
  }

  // Pass 2b: vertices on the cut z-edges between slice pz and pz + 1.
  void add_layer_vertices(Index pz, const Slice& lower, const Slice& upper) {
    for (Index y = 0; y < height_; ++y) {
      const XRange range = pair_range(lower, y, upper, y);
      const std::uint8_t* a = lower.inside.data() + width_ * y;
      const std::uint8_t* b = upper.inside.data() + width_ * y;
      const Index end = range.last + 1;
      for (Index x = next_difference(a, b, range.first, end); x < end;
           x = next_difference(a, b, x + 1, end)) {
        const Index i = x + width_ * y;
        z_vertex_[i] = add_edge_vertex(x, y, pz, 2, value(lower, x, y), value(upper, x, y));
      }
    }
  }

  // Pass 3: the boundary cubes of the layer between the two slices.
  void add_cubes(Index layer, const Slice& lower, const Slice& upper) {
    const std::uint8_t* lower_in = lower.inside.data();
    const std::uint8_t* upper_in = upper.inside.data();
    const Index w = width_;
    const std::array<const VertexId*, 5> ids = {lower.x_vertex.data(), lower.y_vertex.data(),
                                                upper.x_vertex.data(), upper.y_vertex.data(),
                                                z_vertex_.data()};
    std::uint8_t* codes = codes_.data();
    for (Index y = 0; y + 1 < height_; ++y) {
      const XRange range = cube_range(lower, upper, y);
      if (range.first > range.last) continue;
      // Cube indices of the range in one branch-free (vectorised) loop; bits 0..3: (x,y)
      // (x+1,y) (x+1,y+1) (x,y+1) of the lower slice, bits 4..7 the same of the upper.
      const std::uint8_t* l0 = lower_in + width_ * y;
      const std::uint8_t* l1 = l0 + w;
      const std::uint8_t* u0 = upper_in + width_ * y;
      const std::uint8_t* u1 = u0 + w;
      for (Index x = range.first; x <= range.last; ++x) {
        codes[x] = static_cast<std::uint8_t>(l0[x] | l0[x + 1] << 1 | l1[x + 1] << 2 |
                                             l1[x] << 3 | u0[x] << 4 | u0[x + 1] << 5 |
                                             u1[x + 1] << 6 | u1[x] << 7);
      }
      const Index end = range.last + 1;
      for (Index x = next_boundary_code(codes, range.first, end); x < end;
           x = next_boundary_code(codes, x + 1, end)) {
        const Index i = x + width_ * y;
        const unsigned c = codes[x];
        const auto first_triangle = static_cast<std::uint32_t>(mesh_.triangles.size());
        const unsigned loops = add_cube(c, i, ids, lower, upper);
        if (options_.cubes != nullptr) {
          cubes_.push_back({static_cast<std::int32_t>(x - pad_),
                            static_cast<std::int32_t>(y - pad_),
                            static_cast<std::int32_t>(layer - pad_), static_cast<std::uint8_t>(c),
                            static_cast<std::uint8_t>(loops), first_triangle});
        }
      }
    }
  }

  // Triangulates cube index c at row position i; returns its loop count.
  unsigned add_cube(unsigned c, Index i, const std::array<const VertexId*, 5>& ids,
                    const Slice& lower, const Slice& upper) {
    unsigned entry = first_[c];
    const unsigned decided = decided_faces_[c];
    const unsigned ambiguous = kCubeAmbiguousFaces[c];
    if (decided != 0) entry += decide_faces(c, decided, i, lower, upper);
    if (options_.stats != nullptr) {
      ++stats_.boundary_cubes;
      ++stats_.cubes_with_ambiguous_faces[kAmbiguousFaceCount[c]];
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
    return cube_case.loop_count;
  }

  // Decisions on the faces in `faces` (a subset of c's ambiguous faces), packed in face order:
  // bit k = the k-th face of `faces` joins its inside corners.
  unsigned decide_faces(unsigned c, unsigned faces, Index i, const Slice& lower,
                        const Slice& upper) const {
    const Index x = i % width_;
    const Index y = i / width_;
    float corner[kCubeVertexCount];
    for (int v = 0; v < kCubeVertexCount; ++v) {
      const auto& o = kCubeVertexOffset[v];
      corner[v] = value(o[2] == 0 ? lower : upper, x + o[0], y + o[1]);
    }
    unsigned decisions = 0;
    int k = 0;
    for (unsigned rest = faces; rest != 0; rest &= rest - 1, ++k) {
      const auto& f = kCubeFaceVertices[std::countr_zero(rest)];
      // Hand the decider the inside diagonal first; which corner starts does not matter.
      const bool first_inside = ((c >> f[0]) & 1u) != 0;
      const int a = first_inside ? 0 : 1;
      if (detail::face_joins_inside(corner[f[a]], corner[f[a + 1]], corner[f[(a + 2) % 4]],
                                    corner[f[(a + 3) % 4]], iso_)) {
        decisions |= 1u << k;
      }
    }
    return decisions;
  }

  // The vertex on the lattice edge from padded sample (x, y, z) one step along `axis`, whose
  // values are `lo` there and `hi` at the other end (exactly one of them inside).
  VertexId add_edge_vertex(Index x, Index y, Index z, int axis, float lo, float hi) {
    const bool lo_inside = lo >= iso_;
    const double t = edge_fraction(lo_inside ? lo : hi, lo_inside ? hi : lo, iso_);
    const double s = lo_inside ? t : 1.0 - t;  // from the lower end

    std::array<Index, 3> p_lo = {x - pad_, y - pad_, z - pad_};
    std::array<float, 3> position = {static_cast<float>(p_lo[0]), static_cast<float>(p_lo[1]),
                                     static_cast<float>(p_lo[2])};
    position[axis] = static_cast<float>(static_cast<double>(p_lo[axis]) + s);
    mesh_.positions.push_back(position);
    if (defer_normals_) {
      vertex_edges_.push_back(
          4 * static_cast<std::uint64_t>(x + width_ * (y + height_ * z)) +
          static_cast<std::uint64_t>(axis));
    } else if (normals_) {
      std::array<Index, 3> p_hi = p_lo;
      ++p_hi[axis];
      mesh_.normals.push_back(lo_inside ? edge_normal(volume_, p_lo, p_hi, axis, t)
                                        : edge_normal(volume_, p_hi, p_lo, axis, t));
    }
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
      for (int a = 0; a < 3; ++a) position[a] += mesh_.positions[v][a];
      if (!defer_normals_ && !normals_) continue;
      const std::array<float, 3> vertex_normal =
          defer_normals_ ? detail::deferred_vertex_normal(volume_, iso_, options_.close_borders,
                                                          vertex_edges_[v], centroid_normals_)
                         : mesh_.normals[v];
      for (int a = 0; a < 3; ++a) normal[a] += vertex_normal[a];
    }
    const double length =
        std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    const double scale = length > 0.0 ? 1.0 / length : 0.0;
    mesh_.positions.push_back({static_cast<float>(position[0] / count),
                               static_cast<float>(position[1] / count),
                               static_cast<float>(position[2] / count)});
    const std::array<float, 3> centre_normal = {static_cast<float>(normal[0] * scale),
                                                static_cast<float>(normal[1] * scale),
                                                static_cast<float>(normal[2] * scale)};
    if (defer_normals_) {
      vertex_edges_.push_back(4 * centroid_normals_.size() + kCentroidEdge);
      centroid_normals_.push_back(centre_normal);
    } else if (normals_) {
      mesh_.normals.push_back(centre_normal);
    }
    return static_cast<VertexId>(mesh_.positions.size() - 1);
  }

  const Volume& volume_;
  float iso_;
  ExtractOptions options_;
  // detail::extract_layers(..., defer_normals): each vertex's edge instead of its normal.
  bool defer_normals_ = false;
  bool normals_ = true;  // gradient normals into mesh_.normals (options.vertex_normals)
  std::vector<std::uint64_t> vertex_edges_;
  std::vector<std::array<float, 3>> centroid_normals_;
  Index pad_ = 0;
  Index width_ = 0;   // padded samples along x
  Index height_ = 0;  // padded samples along y
  Index depth_ = 0;   // padded slices
  const CubeCase* cases_ = nullptr;
  const std::uint16_t* first_ = nullptr;
  const std::uint8_t* decided_faces_ = nullptr;
  std::array<int, kCubeEdgeCount> edge_array_{};
  std::array<Index, kCubeEdgeCount> edge_offset_{};
  std::shared_ptr<detail::SliceBuffers> buffers_;  // the slices' and z_vertex_'s arrays
  Scratch<VertexId> z_vertex_;
  std::vector<std::uint8_t> codes_;  // cube indices of the current cube row
  TriangleMesh mesh_;
  AmbiguityStats stats_;
  std::vector<BoundaryCube> cubes_;
  std::size_t shared_vertices_ = 0;          // leading vertices owned by the slab below
  std::size_t last_slice_first_vertex_ = 0;  // first vertex of the slab's top slice
  std::size_t last_slice_end_vertex_ = 0;    // one past its last
};

}  // namespace

TriangleMesh extract_isosurface(const Volume& volume, float iso, const ExtractOptions& options) {
  assert(volume.sample_bytes() ==
         static_cast<std::size_t>(volume.size().voxels()) * (volume.holds_int16() ? 2 : 4));
  if (options.stats != nullptr) *options.stats = {};
  if (options.cubes != nullptr) options.cubes->clear();
  const unsigned threads = detail::resolve_threads(options.threads);

  const Index layers = Extractor(volume, iso, options).layers();
  if (layers == 0) {
    if (options.slices_done && volume.size().nz > 0) options.slices_done(0, volume.size().nz);
    return {};
  }
  // Slabs of at least kMinSlabLayers layers (the shared slice is classified twice), a few per
  // thread so that uneven layers (bone in a few slices) still balance.
  constexpr Index kMinSlabLayers = 8;
  const Index slab_count =
      threads == 1 ? 1 : std::clamp<Index>(layers / kMinSlabLayers, 1, Index{4} * threads);
  std::vector<Extractor> slabs;
  slabs.reserve(static_cast<std::size_t>(slab_count));
  for (Index k = 0; k < slab_count; ++k) slabs.emplace_back(volume, iso, options);
  auto first_layer = [&](Index k) { return layers * k / slab_count; };
  detail::run_parallel(slabs.size(), threads, [&](std::size_t k, unsigned) {
    const Index slab = static_cast<Index>(k);
    slabs[k].run(first_layer(slab), first_layer(slab + 1));
  });
  if (options.slices_done) options.slices_done(0, volume.size().nz);
  if (slab_count == 1) {
    if (options.stats != nullptr) *options.stats = slabs[0].stats();
    if (options.cubes != nullptr) *options.cubes = std::move(slabs[0].cubes());
    return std::move(slabs[0].mesh());
  }

  // Concatenate: slab k's own vertices start at vertex_base[k]; its shared ids (the slab
  // below's top slice) map to that slice's range in the slab below.
  std::vector<std::size_t> vertex_base(slabs.size() + 1, 0);
  std::vector<std::size_t> triangle_base(slabs.size() + 1, 0);
  std::vector<std::size_t> cube_base(slabs.size() + 1, 0);
  for (std::size_t k = 0; k < slabs.size(); ++k) {
    Extractor& e = slabs[k];
    vertex_base[k + 1] = vertex_base[k] + e.mesh().positions.size() - e.shared_vertices();
    triangle_base[k + 1] = triangle_base[k] + e.mesh().triangles.size();
    cube_base[k + 1] = cube_base[k] + e.cubes().size();
    if (options.stats != nullptr) *options.stats += e.stats();
  }
  assert(vertex_base.back() <= std::numeric_limits<VertexId>::max());
  TriangleMesh mesh;
  mesh.positions.resize(vertex_base.back());
  if (options.vertex_normals) mesh.normals.resize(vertex_base.back());
  mesh.triangles.resize(triangle_base.back());
  if (options.cubes != nullptr) options.cubes->resize(cube_base.back());
  detail::run_parallel(slabs.size(), threads, [&](std::size_t k, unsigned) {
    Extractor& e = slabs[k];
    TriangleMesh& part = e.mesh();
    const std::size_t shared = e.shared_vertices();
    std::copy(part.positions.begin() + static_cast<std::ptrdiff_t>(shared), part.positions.end(),
              mesh.positions.begin() + static_cast<std::ptrdiff_t>(vertex_base[k]));
    if (options.vertex_normals) {
      std::copy(part.normals.begin() + static_cast<std::ptrdiff_t>(shared), part.normals.end(),
                mesh.normals.begin() + static_cast<std::ptrdiff_t>(vertex_base[k]));
    }
    const auto own = static_cast<VertexId>(vertex_base[k] - shared);
    const auto below =
        k == 0 ? VertexId{0}
               : static_cast<VertexId>(vertex_base[k - 1] + slabs[k - 1].last_slice_first_vertex() -
                                       slabs[k - 1].shared_vertices());
    auto* out = mesh.triangles.data() + triangle_base[k];
    for (const auto& tri : part.triangles) {
      for (int c = 0; c < 3; ++c) (*out)[c] = tri[c] < shared ? below + tri[c] : own + tri[c];
      ++out;
    }
    if (options.cubes != nullptr) {
      BoundaryCube* cube = options.cubes->data() + cube_base[k];
      for (BoundaryCube c : e.cubes()) {
        c.first_triangle += static_cast<std::uint32_t>(triangle_base[k]);
        *cube++ = c;
      }
    }
    part = TriangleMesh{};  // free as we go: peak is the output plus what is left of the parts
  });
  return mesh;
}

namespace detail {

std::int64_t cube_layer_count(const Volume& volume, float iso, const ExtractOptions& options) {
  return Extractor(volume, iso, options).layers();
}

std::array<float, 3> deferred_vertex_normal(
    const Volume& volume, float iso, bool close_borders, std::uint64_t edge,
    const std::vector<std::array<float, 3>>& centroid_normals) {
  const auto axis = static_cast<int>(edge % 4);
  if (axis == static_cast<int>(kCentroidEdge)) return centroid_normals[edge / 4];
  const Index pad = close_borders ? 1 : 0;
  const Index width = volume.size().nx + 2 * pad;
  const Index height = volume.size().ny + 2 * pad;
  const auto cell = static_cast<Index>(edge / 4);
  std::array<Index, 3> p_lo = {cell % width - pad, cell / width % height - pad,
                               cell / width / height - pad};
  std::array<Index, 3> p_hi = p_lo;
  ++p_hi[axis];
  const float lo = is_sample(volume, p_lo) ? volume.at(p_lo[0], p_lo[1], p_lo[2]) : kPadding;
  const float hi = is_sample(volume, p_hi) ? volume.at(p_hi[0], p_hi[1], p_hi[2]) : kPadding;
  const bool lo_inside = lo >= iso;
  const double t = edge_fraction(lo_inside ? lo : hi, lo_inside ? hi : lo, iso);
  return lo_inside ? edge_normal(volume, p_lo, p_hi, axis, t)
                   : edge_normal(volume, p_hi, p_lo, axis, t);
}

std::byte* SliceBuffers::reserve(std::size_t bytes) {
  if (bytes > bytes_) {
    block_.reset();
    bytes_ = 0;
    block_ = std::make_unique_for_overwrite<std::byte[]>(bytes);
    bytes_ = bytes;
  }
  return block_.get();
}

void SliceBuffers::release_pages() { release_whole_pages(block_.get(), bytes_); }

SurfacePiece extract_layers(const Volume& volume, float iso, const ExtractOptions& options,
                            std::int64_t first, std::int64_t last, bool defer_normals,
                            double expected_vertices, SurfacePiece* recycled,
                            LayerObserver* observer) {
  assert(0 <= first && first < last && last <= cube_layer_count(volume, iso, options));
  // The extractor records cubes, and counts ambiguities, when these are set; it keeps both
  // itself (the piece takes them), so the targets stay empty.
  std::vector<BoundaryCube> unused_cubes;
  AmbiguityStats unused_stats;
  ExtractOptions with_cubes = options;
  with_cubes.cubes = &unused_cubes;
  if (options.stats != nullptr) with_cubes.stats = &unused_stats;
  Extractor extractor(volume, iso, with_cubes, defer_normals);
  if (recycled != nullptr) extractor.reuse(std::move(*recycled));
  extractor.run(first, last, expected_vertices, observer);
  SurfacePiece piece;
  piece.mesh = std::move(extractor.mesh());
  piece.vertex_edges = std::move(extractor.vertex_edges());
  piece.centroid_normals = std::move(extractor.centroid_normals());
  piece.cubes = std::move(extractor.cubes());
  piece.slice_buffers = std::move(extractor.slice_buffers());
  piece.stats = extractor.stats();
  piece.shared_vertices = extractor.shared_vertices();
  piece.top_first = extractor.last_slice_first_vertex();
  piece.top_end = extractor.last_slice_end_vertex();
  return piece;
}

}  // namespace detail

}  // namespace typemerge::core
