#include "core/fused_merge.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

#include "core/parallel.h"
#include "core/type_merging_tables.h"

namespace typemerge::core {

FusedMergeStats& FusedMergeStats::operator+=(const FusedMergeStats& part) {
  triangles_before += part.triangles_before;
  vertices_before += part.vertices_before;
  triangles_after += part.triangles_after;
  vertices_after += part.vertices_after;
  for (std::size_t k = 0; k < blocks_merged.size(); ++k) blocks_merged[k] += part.blocks_merged[k];
  rejected_configuration += part.rejected_configuration;
  rejected_topology += part.rejected_topology;
  rejected_facing += part.rejected_facing;
  rejected_flatness += part.rejected_flatness;
  rejected_outline += part.rejected_outline;
  blocks_demoted += part.blocks_demoted;
  face_vertices_removed += part.face_vertices_removed;
  face_vertices_restored += part.face_vertices_restored;
  triangulation_passes += part.triangulation_passes;
  return *this;
}

namespace {

using VertexId = std::uint32_t;
using Triangle = std::array<VertexId, 3>;
using P3 = std::array<double, 3>;
constexpr VertexId kNone = std::numeric_limits<VertexId>::max();

P3 to_double(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }
P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
P3 cross(const P3& a, const P3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// A block: cubes [lo, hi) along each axis (positions [lo, hi] in index space).
struct Box {
  std::array<std::int32_t, 3> lo;
  std::array<std::int32_t, 3> hi;
};

// Twice the signed area of the 2D triangle (a, b, c); > 0 when counter-clockwise.
double orient2d(const std::array<double, 2>& a, const std::array<double, 2>& b,
                const std::array<double, 2>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

// Smallest twice-area (index units², in the projection) of a new triangle: far above float
// rounding of positions, so no written triangle has zero area.
constexpr double kMinDoubleArea = 1e-6;

// A block that passed every test, its loop in loops_[loop_first, loop_first + loop_size).
struct MergedBlock {
  Box box;
  P3 normal;
  double band = 0.0;  // thickness of the slab its disk lies in
  std::uint32_t loop_first = 0;
  std::uint32_t loop_size = 0;
  std::uint32_t cubes_first = 0;  // its cubes: block_cubes_[cubes_first, + cube_count)
  std::uint32_t cube_count = 0;
  std::uint32_t face_count = 0;   // its marching-cubes triangles
  std::int32_t size = 0;          // its edge in cubes
  // Its triangles: made_[made_first, + made_count) once triangulated; demoted = it could not
  // be (or not with fewer triangles than marching cubes), so its cubes keep theirs.
  std::uint32_t made_first = 0;
  std::uint32_t made_count = 0;
  bool demoted = false;
};

// Merges the blocks of one piece and keeps the triangles it emits, in three steps over the
// piece (the window): (1) every block is tested, largest first, and the cubes of no merged
// block keep their marching-cubes triangles; (2) the loop vertices inside a face shared by two
// merged blocks are thinned, the same for both (Douglas–Peucker against the face's polyline,
// within what the two slabs leave of epsilon); (3) every merged block's thinned loop is
// triangulated, and a block that cannot be gets its vertices back, with its neighbours
// triangulated again, until none fails (with every vertex back a loop is the one step 1
// triangulated).
class PieceMerger {
 public:
  PieceMerger(const TriangleMesh& mesh, std::span<const BoundaryCube> cubes,
              const FusedMergeOptions& options, FusedMergeStats& stats)
      : mesh_(mesh),
        cubes_(cubes),
        epsilon_(options.epsilon_voxels),
        stats_(stats),
        stamp_(mesh.positions.size(), 0),
        local_(mesh.positions.size(), 0),
        owner_(cubes.size(), kNone),
        state_(mesh.positions.size(), kOpen) {
    out_.reserve(mesh.triangles.size() / 2);
  }

  // Merges every block of `block` cubes of the piece's lattice box `lattice`, in scan order
  // of the blocks (z, y, x), their halves in the same order.
  void run(const Box& lattice, std::int32_t block) {
    lattice_ = lattice;
    index_rows();
    test_blocks(block);
    thin_shared_faces();
    triangulate_blocks();
  }

  std::vector<Triangle>& triangles() { return out_; }

 private:
  enum VertexState : std::uint8_t { kOpen = 0, kRemoved = 1, kKept = 2 };

  std::span<const Triangle> triangles_of(std::uint32_t cube) const {
    const std::size_t first = cubes_[cube].first_triangle;
    const std::size_t end =
        cube + 1 < cubes_.size() ? cubes_[cube + 1].first_triangle : mesh_.triangles.size();
    return std::span(mesh_.triangles).subspan(first, end - first);
  }

  // Where each row (y, z) of cubes starts in cubes_, for finding a cube by its coordinates.
  void index_rows() {
    row_width_ = lattice_.hi[1] - lattice_.lo[1];
    const std::size_t rows =
        static_cast<std::size_t>(row_width_) * (lattice_.hi[2] - lattice_.lo[2]) + 1;
    row_start_.assign(rows, 0);
    for (const BoundaryCube& c : cubes_) ++row_start_[row_of(c.y, c.z) + 1];
    for (std::size_t r = 1; r < rows; ++r) row_start_[r] += row_start_[r - 1];
  }
  std::size_t row_of(std::int32_t y, std::int32_t z) const {
    return static_cast<std::size_t>(z - lattice_.lo[2]) * row_width_ +
           static_cast<std::size_t>(y - lattice_.lo[1]);
  }
  // The merged block owning cube (x, y, z), or kNone (no such boundary cube in the piece, or
  // it keeps its marching-cubes triangles).
  std::uint32_t owner_of(std::int32_t x, std::int32_t y, std::int32_t z) const {
    for (int a = 0; a < 3; ++a) {
      const std::int32_t c = a == 0 ? x : a == 1 ? y : z;
      if (c < lattice_.lo[a] || c >= lattice_.hi[a]) return kNone;
    }
    const std::size_t row = row_of(y, z);
    const auto first = cubes_.begin() + row_start_[row];
    const auto last = cubes_.begin() + row_start_[row + 1];
    const auto it = std::lower_bound(first, last, x,
                                     [](const BoundaryCube& c, std::int32_t v) { return c.x < v; });
    if (it == last || it->x != x) return kNone;
    return owner_[static_cast<std::size_t>(it - cubes_.begin())];
  }

  // ---- Step 1: test the blocks ----------------------------------------------------------------

  void test_blocks(std::int32_t block) {
    std::vector<std::uint32_t> order;
    std::vector<std::uint32_t> bucket_start;
    const std::int32_t bx = (lattice_.hi[0] - lattice_.lo[0] + block - 1) / block;
    const std::int32_t by = (lattice_.hi[1] - lattice_.lo[1] + block - 1) / block;
    std::size_t c = 0;
    while (c < cubes_.size()) {
      // Cubes are in scan order (z, y, x): the block layer's cubes are a contiguous run.
      const std::int32_t layer = (cubes_[c].z - lattice_.lo[2]) / block;
      std::size_t end = c;
      while (end < cubes_.size() && (cubes_[end].z - lattice_.lo[2]) / block == layer) ++end;
      // Counting sort of the layer's cubes by block (y, x), stable.
      bucket_start.assign(static_cast<std::size_t>(bx) * by + 1, 0);
      auto bucket_of = [&](const BoundaryCube& cube) {
        return static_cast<std::size_t>((cube.y - lattice_.lo[1]) / block) * bx +
               static_cast<std::size_t>((cube.x - lattice_.lo[0]) / block);
      };
      for (std::size_t i = c; i < end; ++i) ++bucket_start[bucket_of(cubes_[i]) + 1];
      for (std::size_t b = 1; b < bucket_start.size(); ++b) bucket_start[b] += bucket_start[b - 1];
      order.resize(end - c);
      {
        std::vector<std::uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
        for (std::size_t i = c; i < end; ++i) {
          order[fill[bucket_of(cubes_[i])]++] = static_cast<std::uint32_t>(i);
        }
      }
      for (std::size_t b = 0; b + 1 < bucket_start.size(); ++b) {
        if (bucket_start[b] == bucket_start[b + 1]) continue;
        const auto yb = static_cast<std::int32_t>(b / static_cast<std::size_t>(bx));
        const auto xb = static_cast<std::int32_t>(b % static_cast<std::size_t>(bx));
        Box box;
        box.lo = {lattice_.lo[0] + xb * block, lattice_.lo[1] + yb * block,
                  lattice_.lo[2] + layer * block};
        for (int a = 0; a < 3; ++a) box.hi[a] = std::min(box.lo[a] + block, lattice_.hi[a]);
        test_block(std::span(order).subspan(bucket_start[b], bucket_start[b + 1] - bucket_start[b]),
                   box, block);
      }
      c = end;
    }
  }

  // Tests the block bottom up: its eight halves first (down to 2 × 2 × 2, whose cubes keep
  // their marching-cubes triangles when it fails), then, when every half that has cubes
  // merged, the block itself, which replaces them if it passes. (Top down, most triangles
  // were tested at every size: 2.5× the time for about 1 % fewer triangles.) Returns whether
  // the block's cubes all belong to merged blocks.
  bool test_block(std::span<std::uint32_t> cubes, const Box& box, std::int32_t size) {
    if (cubes.empty()) return true;
    if (size <= 2) {
      if (try_merge(cubes, box, size)) return true;
      for (std::uint32_t cube : cubes) {
        for (const Triangle& t : triangles_of(cube)) out_.push_back(t);
      }
      return false;
    }
    const std::int32_t half = size / 2;
    // Stable partition into the eight octants, in scan order (z, then y, then x).
    std::array<std::size_t, 9> start{};
    auto octant = [&](std::uint32_t cube) {
      const BoundaryCube& c = cubes_[cube];
      return (c.x >= box.lo[0] + half ? 1 : 0) | (c.y >= box.lo[1] + half ? 2 : 0) |
             (c.z >= box.lo[2] + half ? 4 : 0);
    };
    for (std::uint32_t cube : cubes) ++start[octant(cube) + 1];
    for (int k = 1; k < 9; ++k) start[k] += start[k - 1];
    scratch_order_.assign(cubes.begin(), cubes.end());
    {
      std::array<std::size_t, 8> fill;
      std::copy_n(start.begin(), 8, fill.begin());
      for (std::uint32_t cube : scratch_order_) cubes[fill[octant(cube)]++] = cube;
    }
    const std::size_t blocks_before = blocks_.size();
    const std::size_t loops_before = loops_.size();
    const std::size_t cubes_before = block_cubes_.size();
    bool all = true;
    for (int k = 0; k < 8; ++k) {
      Box child;
      for (int a = 0; a < 3; ++a) {
        const std::int32_t offset = (k >> a) & 1 ? half : 0;
        child.lo[a] = box.lo[a] + offset;
        child.hi[a] = std::min(child.lo[a] + half, box.hi[a]);
      }
      all = test_block(cubes.subspan(start[k], start[k + 1] - start[k]), child, half) && all;
    }
    if (!all || !try_merge(cubes, box, size)) return all;
    // The block replaces its halves, which were the last ones recorded.
    MergedBlock self = blocks_.back();
    std::copy(loops_.begin() + self.loop_first, loops_.end(), loops_.begin() + loops_before);
    loops_.resize(loops_before + self.loop_size);
    std::copy(block_cubes_.begin() + self.cubes_first, block_cubes_.end(),
              block_cubes_.begin() + cubes_before);
    block_cubes_.resize(cubes_before + self.cube_count);
    self.loop_first = static_cast<std::uint32_t>(loops_before);
    self.cubes_first = static_cast<std::uint32_t>(cubes_before);
    blocks_.resize(blocks_before);
    blocks_.push_back(self);
    for (std::uint32_t cube : cubes) owner_[cube] = static_cast<std::uint32_t>(blocks_before);
    return true;
  }

  // Face bits of a position on the box: bit 2a (low face) and 2a + 1 (high face) of axis a.
  static unsigned face_mask(const std::array<float, 3>& p, const Box& box) {
    unsigned mask = 0;
    for (int a = 0; a < 3; ++a) {
      if (p[a] == static_cast<float>(box.lo[a])) mask |= 1u << (2 * a);
      if (p[a] == static_cast<float>(box.hi[a])) mask |= 2u << (2 * a);
    }
    return mask;
  }

  bool try_merge(std::span<const std::uint32_t> cubes, const Box& box, std::int32_t size) {
    std::size_t face_count = 0;
    for (std::uint32_t cube : cubes) {
      if (!type_of(cubes_[cube].index).plane_producible) {
        ++stats_.rejected_configuration;
        return false;
      }
      face_count += triangles_of(cube).size();
    }
    // The block-local vertex table, by stamps (no clearing per block).
    if (++visit_ == 0) {
      std::fill(stamp_.begin(), stamp_.end(), 0);
      visit_ = 1;
    }
    vertices_.clear();
    masks_.clear();
    next_.clear();
    areas_.clear();
    P3 normal{0, 0, 0};
    std::size_t loop_edges = 0;
    for (std::uint32_t cube : cubes) {
      for (const Triangle& t : triangles_of(cube)) {
        std::array<std::uint32_t, 3> l;
        for (int k = 0; k < 3; ++k) {
          const VertexId v = t[k];
          if (stamp_[v] != visit_) {
            stamp_[v] = visit_;
            local_[v] = static_cast<std::uint32_t>(vertices_.size());
            vertices_.push_back(v);
            masks_.push_back(static_cast<std::uint8_t>(face_mask(mesh_.positions[v], box)));
            next_.push_back(kNone);
          }
          l[k] = local_[v];
        }
        for (int k = 0; k < 3; ++k) {
          const std::uint32_t a = l[k];
          const std::uint32_t b = l[(k + 1) % 3];
          if ((masks_[a] & masks_[b]) == 0) continue;
          // An edge on a block face: a loop edge, directed as its triangle has it.
          if (next_[a] != kNone) {
            ++stats_.rejected_topology;  // two loop edges leave one vertex: not one loop
            return false;
          }
          next_[a] = b;
          ++loop_edges;
        }
        const P3 p0 = to_double(mesh_.positions[t[0]]);
        const P3 area = cross(sub(to_double(mesh_.positions[t[1]]), p0),
                              sub(to_double(mesh_.positions[t[2]]), p0));
        areas_.push_back(area);
        for (int a = 0; a < 3; ++a) normal[a] += area[a];
      }
    }
    const std::size_t half_edges = 3 * face_count + loop_edges;
    const auto euler = static_cast<std::int64_t>(vertices_.size()) -
                       static_cast<std::int64_t>(half_edges / 2) +
                       static_cast<std::int64_t>(face_count);
    if (half_edges % 2 != 0 || euler != 1 || loop_edges < 3) {
      ++stats_.rejected_topology;
      return false;
    }
    // One loop: following it from a loop vertex comes back after all loop edges.
    loop_.clear();
    {
      std::uint32_t start = 0;
      while (next_[start] == kNone) ++start;
      std::uint32_t v = start;
      do {
        loop_.push_back(vertices_[v]);
        v = next_[v];
      } while (v != start && v != kNone && loop_.size() <= loop_edges);
      if (v != start || loop_.size() != loop_edges) {
        ++stats_.rejected_topology;
        return false;
      }
    }
    const double length = std::sqrt(dot(normal, normal));
    if (!(length > 0.0)) {
      ++stats_.rejected_facing;
      return false;
    }
    for (double& c : normal) c /= length;
    for (const P3& area : areas_) {
      if (!(dot(area, normal) > 0.0)) {
        ++stats_.rejected_facing;
        return false;
      }
    }
    double low = std::numeric_limits<double>::max();
    double high = std::numeric_limits<double>::lowest();
    for (VertexId v : vertices_) {
      const double h = dot(to_double(mesh_.positions[v]), normal);
      low = std::min(low, h);
      high = std::max(high, h);
    }
    if (high - low > epsilon_) {
      ++stats_.rejected_flatness;
      return false;
    }
    project(loop_, box, normal);
    if (!flat_is_simple()) {
      ++stats_.rejected_outline;
      return false;
    }
    MergedBlock merged;
    merged.box = box;
    merged.normal = normal;
    merged.band = high - low;
    merged.loop_first = static_cast<std::uint32_t>(loops_.size());
    merged.loop_size = static_cast<std::uint32_t>(loop_.size());
    merged.cubes_first = static_cast<std::uint32_t>(block_cubes_.size());
    merged.cube_count = static_cast<std::uint32_t>(cubes.size());
    merged.face_count = static_cast<std::uint32_t>(face_count);
    merged.size = size;
    block_cubes_.insert(block_cubes_.end(), cubes.begin(), cubes.end());
    loops_.insert(loops_.end(), loop_.begin(), loop_.end());
    const auto id = static_cast<std::uint32_t>(blocks_.size());
    blocks_.push_back(merged);
    for (std::uint32_t cube : cubes) owner_[cube] = id;
    return true;
  }

  // ---- Step 2: thin the faces two merged blocks share -------------------------------------------

  // The other merged block when v lies inside a face shared by merged block `self` and one
  // other merged block (the four cubes around v's lattice edge are theirs), else kNone.
  std::uint32_t partner(VertexId v, std::uint32_t self) const {
    const std::array<float, 3>& p = mesh_.positions[v];
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (p[a] != std::floor(p[a])) axis = a;
    }
    if (axis < 0) return kNone;
    const int b = (axis + 1) % 3;
    const int c = (axis + 2) % 3;
    std::array<std::int32_t, 3> cell;
    cell[axis] = static_cast<std::int32_t>(std::floor(p[axis]));
    std::uint32_t other = kNone;
    int own = 0;
    for (int k = 0; k < 4; ++k) {
      cell[b] = static_cast<std::int32_t>(p[b]) - 1 + (k & 1);
      cell[c] = static_cast<std::int32_t>(p[c]) - 1 + (k >> 1);
      const std::uint32_t o = owner_of(cell[0], cell[1], cell[2]);
      if (o == kNone) return kNone;
      if (o == self) {
        ++own;
      } else if (other == kNone || other == o) {
        other = o;
      } else {
        return kNone;
      }
    }
    return own == 2 ? other : kNone;
  }

  static double point_segment_distance(const P3& p, const P3& a, const P3& b) {
    const P3 ab = sub(b, a);
    const P3 ap = sub(p, a);
    const double len = dot(ab, ab);
    const double t = len > 0.0 ? std::clamp(dot(ap, ab) / len, 0.0, 1.0) : 0.0;
    const P3 d = {ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]};
    return std::sqrt(dot(d, d));
  }

  // Whether two vertices lie on one lattice line (same edge axis, same other coordinates).
  bool on_one_lattice_line(VertexId u, VertexId w) const {
    const std::array<float, 3>& p = mesh_.positions[u];
    const std::array<float, 3>& q = mesh_.positions[w];
    int same = 0;
    for (int a = 0; a < 3; ++a) {
      if (p[a] == q[a] && p[a] == std::floor(p[a])) ++same;
    }
    return same >= 2;
  }

  // Douglas–Peucker on run[first..last] (the ends kept): marks the inner vertices removed
  // where the shortcut passes within `tolerance`, else keeps the farthest and recurses.
  void thin_run(std::span<const VertexId> run, std::size_t first, std::size_t last,
                double tolerance) {
    if (last <= first + 1) return;
    const P3 a = to_double(mesh_.positions[run[first]]);
    const P3 b = to_double(mesh_.positions[run[last]]);
    std::size_t far = first;
    double far_distance = -1.0;
    for (std::size_t k = first + 1; k < last; ++k) {
      const double d = point_segment_distance(to_double(mesh_.positions[run[k]]), a, b);
      if (d > far_distance) {
        far_distance = d;
        far = k;
      }
    }
    // A shortcut along a lattice line would lie on the face's border (or on a cube edge),
    // which other blocks share: it could duplicate their edge.
    if (far_distance <= tolerance && !on_one_lattice_line(run[first], run[last])) {
      for (std::size_t k = first + 1; k < last; ++k) state_[run[k]] = kRemoved;
      stats_.face_vertices_removed += last - first - 1;
      return;
    }
    state_[run[far]] = kKept;
    thin_run(run, first, far, tolerance);
    thin_run(run, far, last, tolerance);
  }

  void thin_shared_faces() {
    std::vector<std::uint32_t> partners;
    std::vector<VertexId> run;
    for (std::uint32_t id = 0; id < blocks_.size(); ++id) {
      const MergedBlock& block = blocks_[id];
      const std::span<const VertexId> loop(loops_.data() + block.loop_first, block.loop_size);
      const std::size_t n = loop.size();
      partners.resize(n);
      for (std::size_t k = 0; k < n; ++k) {
        partners[k] = state_[loop[k]] == kOpen ? partner(loop[k], id) : kNone;
      }
      // Runs of one partner between two vertices that stay (a run's ends lie on the face's
      // border, where a third block or a marching-cubes cube meets it).
      std::size_t start = 0;
      while (start < n && partners[start] != kNone) ++start;
      if (start == n) continue;
      for (std::size_t k = 1; k <= n;) {
        const std::size_t i = (start + k) % n;
        if (partners[i] == kNone) {
          ++k;
          continue;
        }
        const std::uint32_t other = partners[i];
        run.assign(1, loop[(start + k - 1) % n]);
        std::size_t j = k;
        while (j <= n && partners[(start + j) % n] == other) run.push_back(loop[(start + j++) % n]);
        const std::size_t end = (start + j) % n;
        if (partners[end] != kNone) {
          // Two partners meet without a vertex between (not expected): keep the run.
          for (std::size_t r = 1; r < run.size(); ++r) state_[run[r]] = kKept;
        } else {
          run.push_back(loop[end]);
          const double tolerance = epsilon_ - std::max(block.band, blocks_[other].band);
          thin_run(run, 0, run.size() - 1, tolerance);
          for (std::size_t r = 1; r + 1 < run.size(); ++r) {
            if (state_[run[r]] == kOpen) state_[run[r]] = kKept;
          }
        }
        k = j;
      }
    }
  }

  // ---- Step 3: triangulate --------------------------------------------------------------------

  // Gives back every thinned vertex of the block's loop; the other block of each (the only
  // other block the vertex's loop passes through) must be triangulated again.
  void restore_loop(const MergedBlock& block, std::uint32_t id, std::vector<std::uint32_t>& again) {
    for (std::uint32_t k = 0; k < block.loop_size; ++k) {
      const VertexId v = loops_[block.loop_first + k];
      if (state_[v] != kRemoved) continue;
      state_[v] = kKept;
      ++stats_.face_vertices_restored;
      const std::uint32_t other = partner(v, id);
      if (other != kNone) again.push_back(other);
    }
  }

  void triangulate_blocks() {
    std::vector<VertexId> loop;
    std::vector<std::uint32_t> todo(blocks_.size());
    for (std::uint32_t id = 0; id < todo.size(); ++id) todo[id] = id;
    std::vector<std::uint32_t> again;
    while (!todo.empty()) {
      ++stats_.triangulation_passes;
      again.clear();
      for (std::uint32_t id : todo) {
        MergedBlock& block = blocks_[id];
        if (block.demoted) continue;
        const std::span<const VertexId> full(loops_.data() + block.loop_first, block.loop_size);
        loop.clear();
        for (VertexId v : full) {
          if (state_[v] != kRemoved) loop.push_back(v);
        }
        const std::size_t before = made_.size();
        // No more triangles than marching cubes (a loop of n makes n − 2).
        const bool done = loop.size() - 2 <= block.face_count &&
                          triangulate(loop, block.box, block.normal, made_,
                                      loop.size() != full.size()) == Triangulation::kDone;
        if (done) {
          block.made_first = static_cast<std::uint32_t>(before);
          block.made_count = static_cast<std::uint32_t>(made_.size() - before);
          continue;
        }
        made_.resize(before);
        if (loop.size() == full.size()) {
          // Not even the whole loop: the block keeps its marching-cubes triangles.
          block.demoted = true;
          ++stats_.blocks_demoted;
          for (std::uint32_t c = 0; c < block.cube_count; ++c) {
            owner_[block_cubes_[block.cubes_first + c]] = kNone;
          }
        }
        restore_loop(block, id, again);
        again.push_back(id);
      }
      std::sort(again.begin(), again.end());
      again.erase(std::unique(again.begin(), again.end()), again.end());
      todo.swap(again);
    }
    for (const MergedBlock& block : blocks_) {
      if (block.demoted) {
        for (std::uint32_t c = 0; c < block.cube_count; ++c) {
          for (const Triangle& t : triangles_of(block_cubes_[block.cubes_first + c])) {
            out_.push_back(t);
          }
        }
      } else {
        ++stats_.blocks_merged[static_cast<std::size_t>(
                                   std::countr_zero(static_cast<unsigned>(block.size))) -
                               1];
        out_.insert(out_.end(), made_.begin() + block.made_first,
                    made_.begin() + block.made_first + block.made_count);
      }
    }
  }

  enum class Triangulation { kDone, kNotSimple, kStuck };

  // Triangulates `loop` (CCW about n) by ears in the projection along n into `out`; nothing
  // is added unless it succeeds. check_outline: test that the projected loop is simple
  // (known for a loop step 1 tested, i.e. not thinned).
  Triangulation triangulate(std::span<const VertexId> loop, const Box& box, const P3& n,
                            std::vector<Triangle>& out, bool check_outline) {
    project(loop, box, n);
    if (check_outline && !flat_is_simple()) return Triangulation::kNotSimple;
    const std::size_t before = out.size();
    if (!clip_ears(loop, out)) {
      out.resize(before);
      return Triangulation::kStuck;
    }
    return Triangulation::kDone;
  }

  // The loop in 2D: coordinates in a basis (u, w) with u × w = n, so the loop (CCW about n)
  // is counter-clockwise; with its face masks on the box.
  void project(std::span<const VertexId> loop, const Box& box, const P3& n) {
    const int axis = std::fabs(n[0]) < std::fabs(n[1])
                         ? (std::fabs(n[0]) < std::fabs(n[2]) ? 0 : 2)
                         : (std::fabs(n[1]) < std::fabs(n[2]) ? 1 : 2);
    P3 e{0, 0, 0};
    e[axis] = 1.0;
    P3 u = cross(e, n);
    const double ul = std::sqrt(dot(u, u));
    for (double& c : u) c /= ul;
    const P3 w = cross(n, u);
    flat_.clear();
    flat_masks_.clear();
    for (VertexId v : loop) {
      const P3 p = to_double(mesh_.positions[v]);
      flat_.push_back({dot(p, u), dot(p, w)});
      flat_masks_.push_back(static_cast<std::uint8_t>(face_mask(mesh_.positions[v], box)));
    }
  }

  // Counter-clockwise, and no two edges of the projected loop meet except consecutive ones
  // at their shared corner.
  bool flat_is_simple() const {
    const std::size_t n = flat_.size();
    if (n < 3) return false;
    double area = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = flat_[i];
      const auto& b = flat_[(i + 1) % n];
      area += a[0] * b[1] - a[1] * b[0];
    }
    if (!(area > 0.0)) return false;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& a = flat_[i];
      const auto& b = flat_[(i + 1) % n];
      for (std::size_t j = i + 1; j < n; ++j) {
        const auto& c = flat_[j];
        const auto& d = flat_[(j + 1) % n];
        const bool after = j == i + 1;
        const bool before = (j + 1) % n == i;
        if (after || before) {
          // Consecutive edges fold back onto each other only if collinear and reversed.
          const auto& far = after ? d : c;
          const auto& corner = after ? b : a;
          const auto& other = after ? a : b;
          if (orient2d(other, corner, far) == 0.0 &&
              (far[0] - corner[0]) * (other[0] - corner[0]) +
                      (far[1] - corner[1]) * (other[1] - corner[1]) >
                  0.0) {
            return false;
          }
          continue;
        }
        if (std::max(a[0], b[0]) < std::min(c[0], d[0]) ||
            std::max(c[0], d[0]) < std::min(a[0], b[0]) ||
            std::max(a[1], b[1]) < std::min(c[1], d[1]) ||
            std::max(c[1], d[1]) < std::min(a[1], b[1])) {
          continue;
        }
        // Closed segments meet (collinear overlap included, conservatively).
        if (orient2d(a, b, c) * orient2d(a, b, d) <= 0.0 &&
            orient2d(c, d, a) * orient2d(c, d, b) <= 0.0) {
          return false;
        }
      }
    }
    return true;
  }

  // Shape of the 3D triangle of loop vertices (a, b, c): 1 − the cosine of its smallest
  // angle, so larger is better.
  double shape(VertexId a, VertexId b, VertexId c) const {
    const P3 pa = to_double(mesh_.positions[a]);
    const P3 pb = to_double(mesh_.positions[b]);
    const P3 pc = to_double(mesh_.positions[c]);
    auto cosine = [](const P3& o, const P3& p, const P3& q) {
      const P3 u = sub(p, o);
      const P3 v = sub(q, o);
      return dot(u, v) / std::sqrt(dot(u, u) * dot(v, v));
    };
    return 1.0 - std::max({cosine(pa, pb, pc), cosine(pb, pc, pa), cosine(pc, pa, pb)});
  }

  // Whether the ear at loop position i (with its current neighbours) may be clipped: convex,
  // empty, and its new edge joins two vertices on no common face of the box (the last
  // triangle: not all three on one face).
  bool ear_valid(std::uint32_t i) const {
    const std::uint32_t a = prev_[i];
    const std::uint32_t c = succ_[i];
    const auto& pa = flat_[a];
    const auto& pi = flat_[i];
    const auto& pc = flat_[c];
    if (!(orient2d(pa, pi, pc) > kMinDoubleArea)) return false;
    const bool last = succ_[c] == a;
    const unsigned ma = flat_masks_[a];
    const unsigned mc = flat_masks_[c];
    if (last ? (ma & mc & flat_masks_[i]) != 0 : (ma & mc) != 0) return false;
    for (std::uint32_t j = succ_[c]; j != a; j = succ_[j]) {
      const auto& p = flat_[j];
      if (orient2d(pa, pi, p) >= 0.0 && orient2d(pi, pc, p) >= 0.0 && orient2d(pc, pa, p) >= 0.0) {
        return false;
      }
    }
    return true;
  }

  // Triangulates the projected loop by clipping, each time, the valid ear of best shape.
  bool clip_ears(std::span<const VertexId> loop, std::vector<Triangle>& out) {
    const auto n = static_cast<std::uint32_t>(loop.size());
    prev_.resize(n);
    succ_.resize(n);
    score_.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      prev_[i] = (i + n - 1) % n;
      succ_[i] = (i + 1) % n;
    }
    auto score_ear = [&](std::uint32_t i) {
      score_[i] = ear_valid(i) ? shape(loop[prev_[i]], loop[i], loop[succ_[i]]) : -1.0;
    };
    for (std::uint32_t i = 0; i < n; ++i) score_ear(i);
    std::uint32_t any = 0;
    for (std::uint32_t left = n; left >= 3; --left) {
      std::uint32_t best = kNone;
      double best_score = -0.5;
      std::uint32_t i = any;
      for (std::uint32_t k = 0; k < left; ++k, i = succ_[i]) {
        if (score_[i] > best_score) {
          best_score = score_[i];
          best = i;
        }
      }
      if (best == kNone) return false;
      const std::uint32_t a = prev_[best];
      const std::uint32_t c = succ_[best];
      out.push_back({loop[a], loop[best], loop[c]});
      if (left == 3) break;
      succ_[a] = c;
      prev_[c] = a;
      any = a;
      score_ear(a);
      score_ear(c);
    }
    return true;
  }

  const TriangleMesh& mesh_;
  std::span<const BoundaryCube> cubes_;
  double epsilon_;
  FusedMergeStats& stats_;
  Box lattice_{};
  std::vector<std::uint32_t> stamp_;  // per piece vertex: the visit that last saw it
  std::vector<std::uint32_t> local_;  // per piece vertex: its block-local index
  std::vector<std::uint32_t> owner_;  // per cube: its merged block, or kNone
  std::vector<std::uint8_t> state_;   // per piece vertex: VertexState
  std::vector<std::uint32_t> row_start_;
  std::int32_t row_width_ = 0;
  std::uint32_t visit_ = 0;
  std::vector<MergedBlock> blocks_;
  std::vector<VertexId> loops_;
  // Block-local scratch, reused.
  std::vector<VertexId> vertices_;
  std::vector<std::uint8_t> masks_;
  std::vector<std::uint32_t> next_;
  std::vector<P3> areas_;
  std::vector<VertexId> loop_;
  std::vector<std::array<double, 2>> flat_;
  std::vector<std::uint8_t> flat_masks_;
  std::vector<std::uint32_t> prev_;
  std::vector<std::uint32_t> succ_;
  std::vector<double> score_;
  std::vector<std::uint32_t> scratch_order_;
  std::vector<std::uint32_t> block_cubes_;  // the cubes of the merged blocks
  std::vector<Triangle> made_;              // the merged blocks' triangles
  std::vector<Triangle> out_;
};

// One piece, merged and compacted.
struct MergedPiece {
  TriangleMesh mesh;
  std::size_t shared = 0;     // its first `shared` vertices are the piece below's top slice
  std::vector<VertexId> top;  // its top slice's vertices (ids in `mesh`), in seam order
  FusedMergeStats stats;
  AmbiguityStats ambiguity;
};

MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const FusedMergeOptions& options, std::int64_t first, std::int64_t last) {
  detail::SurfacePiece piece = detail::extract_layers(volume, iso, extract, first, last);
  MergedPiece out;
  out.shared = piece.shared_vertices;
  out.ambiguity = piece.stats;
  out.stats.triangles_before = piece.mesh.triangles.size();
  out.stats.vertices_before = piece.mesh.positions.size() - piece.shared_vertices;

  const std::int32_t pad = extract.close_borders ? 1 : 0;
  const VolumeSize& size = volume.size();
  Box lattice;
  lattice.lo = {-pad, -pad, static_cast<std::int32_t>(first) - pad};
  lattice.hi = {static_cast<std::int32_t>(size.nx - 1 + pad),
                static_cast<std::int32_t>(size.ny - 1 + pad),
                static_cast<std::int32_t>(last) - pad};
  std::vector<Triangle> triangles;
  {
    PieceMerger merger(piece.mesh, piece.cubes, options, out.stats);
    merger.run(lattice, static_cast<std::int32_t>(options.block_cubes));
    triangles = std::move(merger.triangles());
  }
  piece.cubes = {};

  // Compaction: the vertices still used, in their order (so the seam's stay first, in order).
  std::vector<VertexId> new_id(piece.mesh.positions.size(), kNone);
  for (const Triangle& t : triangles) {
    for (VertexId v : t) new_id[v] = 0;
  }
  VertexId next = 0;
  for (VertexId v = 0; v < new_id.size(); ++v) {
    if (new_id[v] == 0) {
      new_id[v] = next;
      out.mesh.positions.push_back(piece.mesh.positions[v]);
      out.mesh.normals.push_back(piece.mesh.normals[v]);
      ++next;
    }
  }
  for (Triangle& t : triangles) {
    for (VertexId& v : t) v = new_id[v];
  }
  out.mesh.triangles = std::move(triangles);
  // Seam vertices lie on block faces, so they are loop vertices and stay.
  for (std::size_t v = 0; v < out.shared; ++v) {
    if (new_id[v] != v) throw std::logic_error("fused merge dropped a seam vertex");
  }
  for (std::size_t v = piece.top_first; v < piece.top_end; ++v) {
    if (new_id[v] == kNone) throw std::logic_error("fused merge dropped a seam vertex");
    out.top.push_back(new_id[v]);
  }
  out.stats.triangles_after = out.mesh.triangles.size();
  out.stats.vertices_after = out.mesh.positions.size() - out.shared;
  return out;
}

// Appends a merged piece to `out`, joining its shared vertices to `seam` (the output ids of
// the top slice of the piece appended before it), and makes `seam` its own top slice.
void append_piece(TriangleMesh& out, const MergedPiece& piece, std::vector<VertexId>& seam) {
  if (piece.shared != seam.size()) {
    throw std::logic_error("fused merge: pieces disagree about their seam");
  }
  const std::size_t base = out.positions.size() - piece.shared;  // own vertex v → base + v
  if (base + piece.mesh.positions.size() > std::numeric_limits<VertexId>::max()) {
    throw std::length_error("surface has too many vertices for 32-bit indices");
  }
  auto output_id = [&](VertexId v) {
    return v < piece.shared ? seam[v] : static_cast<VertexId>(base + v);
  };
  const auto own = static_cast<std::ptrdiff_t>(piece.shared);
  out.positions.insert(out.positions.end(), piece.mesh.positions.begin() + own,
                       piece.mesh.positions.end());
  out.normals.insert(out.normals.end(), piece.mesh.normals.begin() + own, piece.mesh.normals.end());
  for (const auto& t : piece.mesh.triangles) {
    out.triangles.push_back({output_id(t[0]), output_id(t[1]), output_id(t[2])});
  }
  std::vector<VertexId> top;
  top.reserve(piece.top.size());
  for (VertexId v : piece.top) top.push_back(output_id(v));
  seam = std::move(top);
}

}  // namespace

TriangleMesh extract_fused_merged(const Volume& volume, float iso, const ExtractOptions& extract,
                                  const FusedMergeOptions& options, FusedMergeStats* stats) {
  if (options.block_cubes < 2 || !std::has_single_bit(options.block_cubes) ||
      options.slab_layers % options.block_cubes != 0) {
    throw std::invalid_argument(
        "fused merge: block_cubes must be a power of two >= 2 and slab_layers a multiple of it");
  }
  if (extract.stats != nullptr) *extract.stats = {};
  FusedMergeStats total;
  TriangleMesh out;
  const std::int64_t layers = detail::cube_layer_count(volume, iso, extract);
  const std::int64_t height =
      options.slab_layers > 0 ? static_cast<std::int64_t>(options.slab_layers) : layers;
  const std::int64_t count = layers > 0 ? (layers + height - 1) / height : 0;
  const unsigned threads = std::max(detail::resolve_threads(options.threads),
                                    detail::resolve_threads(extract.threads));
  // Pieces are appended in order as soon as their predecessors are; the output is reserved
  // ahead from the pieces so far (their average × the pieces in all, plus a fifth), so it is
  // not copied by doubling at its largest.
  std::vector<VertexId> seam;
  detail::make_in_order<MergedPiece>(
      static_cast<std::size_t>(count), threads,
      [&](std::size_t i) {
        const auto k = static_cast<std::int64_t>(i);
        return merge_piece(volume, iso, extract, options, k * height,
                           std::min(layers, (k + 1) * height));
      },
      [&](std::size_t i, MergedPiece& piece) {
        const std::size_t vertices =
            out.positions.size() + piece.mesh.positions.size() - piece.shared;
        const std::size_t triangles = out.triangles.size() + piece.mesh.triangles.size();
        if (vertices > out.positions.capacity() || triangles > out.triangles.capacity()) {
          const double scale = 1.2 * static_cast<double>(count) / static_cast<double>(i + 1);
          const auto ahead = [&](std::size_t n) {
            return std::max(n, static_cast<std::size_t>(scale * static_cast<double>(n)));
          };
          out.positions.reserve(ahead(vertices));
          out.normals.reserve(ahead(vertices));
          out.triangles.reserve(ahead(triangles));
        }
        append_piece(out, piece, seam);
        total += piece.stats;
        if (extract.stats != nullptr) *extract.stats += piece.ambiguity;
      });
  if (stats != nullptr) *stats = total;
  return out;
}

}  // namespace typemerge::core
