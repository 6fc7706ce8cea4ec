#include "core/merge/blocks.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <utility>

#include "core/cube_tables.h"

namespace typemerge::core::merge {

Dims block_dims(const IndexToPatient& geometry, const MergeOptions& options) {
  const auto block = static_cast<std::int32_t>(options.block_cubes);
  Dims dims{block, block, block};
  if (!options.blocks_follow_spacing) return dims;
  const double finest = std::min({geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)});
  for (int a = 0; a < 3; ++a) {
    if (geometry.spacing(a) >= std::sqrt(2.0) * finest) dims[a] = block / 2;
  }
  return dims;
}

Dims children_of(const Dims& dims, const std::array<double, 3>& spacing) {
  double longest = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] > 2) longest = std::max(longest, dims[a] * spacing[a]);
  }
  Dims half = dims;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] > 2 && dims[a] * spacing[a] * std::sqrt(2.0) >= longest) half[a] /= 2;
  }
  return half;
}

namespace {

// Bits of a cube index on face f (kCubeFaceVertices).
constexpr std::array<std::uint8_t, kCubeFaceCount> kFaceCorners = [] {
  std::array<std::uint8_t, kCubeFaceCount> table{};
  for (int f = 0; f < kCubeFaceCount; ++f) {
    for (int v : kCubeFaceVertices[f]) table[f] = static_cast<std::uint8_t>(table[f] | (1u << v));
  }
  return table;
}();

// Whether the marching-cubes surface of `cubes` (a box at most two cubes along each axis) is
// one connected piece, from the cubes alone: each cube's surface is one loop, and the cubes
// are joined through the faces the surface crosses (two cubes share the vertices on the edges
// it cuts there; cubes around a cut edge inside the box are joined so through each other).
// False when it is several pieces, or a cube holds several loops (then nothing is known).
bool one_connected_surface(std::span<const BoundaryCube> all, std::span<const std::uint32_t> cubes,
                           const Box& box) {
  std::array<std::uint8_t, 8> index{};  // by slot x + 2y + 4z within the box
  unsigned present = 0;
  for (std::uint32_t c : cubes) {
    const BoundaryCube& cube = all[c];
    if (cube.loops != 1) return false;
    const unsigned slot = static_cast<unsigned>(cube.x - box.lo[0]) |
                          static_cast<unsigned>(cube.y - box.lo[1]) << 1u |
                          static_cast<unsigned>(cube.z - box.lo[2]) << 2u;
    if (slot > 7) return false;
    index[slot] = cube.index;
    present |= 1u << slot;
  }
  // Bit s of joined[axis]: cube s and the cube after it along `axis` are joined (the low
  // cube's high face is crossed: its corners are mixed); then a flood fill over the bits.
  constexpr std::array<unsigned, 3> kLowSlots{0x55, 0x33, 0x0F};
  std::array<unsigned, 3> joined{};
  for (int axis = 0; axis < 3; ++axis) {
    const unsigned face = kFaceCorners[2 * axis + 1];
    for (unsigned low = present & (present >> (1u << axis)) & kLowSlots[axis]; low != 0;
         low &= low - 1) {
      const auto slot = static_cast<unsigned>(std::countr_zero(low));
      const unsigned corners = index[slot] & face;
      if (corners != 0 && corners != face) joined[axis] |= 1u << slot;
    }
  }
  unsigned reached = present & (~present + 1u);  // the lowest cube
  for (unsigned before = 0; reached != before;) {
    before = reached;
    for (int axis = 0; axis < 3; ++axis) {
      const unsigned step = 1u << axis;
      reached |= (reached & joined[axis]) << step | ((reached >> step) & joined[axis]);
    }
  }
  return reached == present;
}

// The pass over one piece: the scratch its recursion reuses, and where it writes.
class BlockPass {
 public:
  BlockPass(const PieceSurface& piece, const std::array<double, 3>& spacing, DiskTest& test,
            DiskStore& store, std::vector<Triangle>& kept, MergeStats& stats)
      : piece_(piece), spacing_(spacing), test_(test), store_(store), kept_(kept), stats_(stats) {}

  void run(const Box& lattice, const Dims& block, std::size_t first_cube);

 private:
  bool test_block(std::span<std::uint32_t> cubes, const Box& box, const Dims& dims);
  std::array<std::pair<std::span<std::uint32_t>, Box>, 2> halves(std::span<std::uint32_t> cubes,
                                                                const Box& box, int axis);
  void try_halves(std::span<std::uint32_t> cubes, const Box& box, std::span<const int> axes);
  bool try_single_cubes(std::span<std::uint32_t> cubes);
  bool try_merge(std::span<const std::uint32_t> cubes, const Box& box, std::int32_t size,
                 bool emit_failures);
  bool try_replacing(const Box& box, std::int32_t size, std::size_t disks_before);

  const PieceSurface& piece_;
  const std::array<double, 3>& spacing_;
  DiskTest& test_;
  DiskStore& store_;
  std::vector<Triangle>& kept_;
  MergeStats& stats_;
  std::vector<TriangleRun> runs_;
  std::vector<std::uint32_t> scratch_order_;
  std::vector<std::uint8_t> scratch_octant_;  // test_block's octant of each cube, by position
  ComposedBlock composed_;
};

void BlockPass::run(const Box& lattice, const Dims& block, std::size_t first_cube) {
  const std::span<const BoundaryCube> cubes = piece_.cubes;
  std::vector<std::uint32_t> order;
  std::vector<std::uint32_t> bucket_start;
  std::vector<std::size_t> bucket;  // of each cube of the layer
  const std::int32_t bx = (lattice.hi[0] - lattice.lo[0] + block[0] - 1) / block[0];
  const std::int32_t by = (lattice.hi[1] - lattice.lo[1] + block[1] - 1) / block[1];
  std::size_t c = first_cube;
  while (c < cubes.size()) {
    // Cubes are in scan order (z, y, x): the block layer's cubes are a contiguous run.
    const std::int32_t layer = (cubes[c].z - lattice.lo[2]) / block[2];
    std::size_t end = c;
    while (end < cubes.size() && (cubes[end].z - lattice.lo[2]) / block[2] == layer) ++end;
    // Counting sort of the layer's cubes by block (y, x), stable.
    bucket_start.assign(static_cast<std::size_t>(bx) * by + 1, 0);
    auto bucket_of = [&](const BoundaryCube& cube) {
      return static_cast<std::size_t>((cube.y - lattice.lo[1]) / block[1]) * bx +
             static_cast<std::size_t>((cube.x - lattice.lo[0]) / block[0]);
    };
    bucket.resize(end - c);
    for (std::size_t i = c; i < end; ++i) {
      bucket[i - c] = bucket_of(cubes[i]);
      ++bucket_start[bucket[i - c] + 1];
    }
    for (std::size_t b = 1; b < bucket_start.size(); ++b) bucket_start[b] += bucket_start[b - 1];
    order.resize(end - c);
    {
      std::vector<std::uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
      for (std::size_t i = c; i < end; ++i) {
        order[fill[bucket[i - c]]++] = static_cast<std::uint32_t>(i);
      }
    }
    for (std::size_t b = 0; b + 1 < bucket_start.size(); ++b) {
      if (bucket_start[b] == bucket_start[b + 1]) continue;
      const auto yb = static_cast<std::int32_t>(b / static_cast<std::size_t>(bx));
      const auto xb = static_cast<std::int32_t>(b % static_cast<std::size_t>(bx));
      Box box;
      box.lo = {lattice.lo[0] + xb * block[0], lattice.lo[1] + yb * block[1],
                lattice.lo[2] + layer * block[2]};
      for (int a = 0; a < 3; ++a) box.hi[a] = std::min(box.lo[a] + block[a], lattice.hi[a]);
      test_block(std::span(order).subspan(bucket_start[b], bucket_start[b + 1] - bucket_start[b]),
                 box, block);
    }
    c = end;
  }
}

// The two halves of a box two cubes thick along `axis`, with their cubes (reordered so that
// the low half's come first, stably).
std::array<std::pair<std::span<std::uint32_t>, Box>, 2> BlockPass::halves(
    std::span<std::uint32_t> cubes, const Box& box, int axis) {
  // A stable two-way partition through scratch_order_ (std::stable_partition would allocate
  // a buffer at every failing block).
  auto low = [&](std::uint32_t c) {
    const BoundaryCube& cube = piece_.cubes[c];
    return (axis == 0 ? cube.x : axis == 1 ? cube.y : cube.z) == box.lo[axis];
  };
  scratch_order_.assign(cubes.begin(), cubes.end());
  std::size_t split = 0;
  for (std::uint32_t c : scratch_order_) {
    if (low(c)) cubes[split++] = c;
  }
  std::size_t rest = split;
  for (std::uint32_t c : scratch_order_) {
    if (!low(c)) cubes[rest++] = c;
  }
  std::array<std::pair<std::span<std::uint32_t>, Box>, 2> out{
      {{cubes.subspan(0, split), box}, {cubes.subspan(split), box}}};
  for (int k = 0; k < 2; ++k) {
    Box& half = out[k].second;
    half.lo[axis] = box.lo[axis] + k;
    half.hi[axis] = std::min(half.lo[axis] + 1, box.hi[axis]);
  }
  return out;
}

// Tests the block bottom up: its eight children first (down to 2 × 2 × 2, which tries its
// layers and rows where it fails), then, when every child that has cubes merged, the block
// itself, which replaces them if it passes. Returns whether the block's cubes all belong to
// merged disks.
bool BlockPass::test_block(std::span<std::uint32_t> cubes, const Box& box, const Dims& dims) {
  if (cubes.empty()) return true;
  const std::int32_t size = std::max({dims[0], dims[1], dims[2]});
  if (size <= 2) {
    // A leaf of one cube (where the lattice ends) is that cube alone, tried once.
    if (one_cube(box)) return try_single_cubes(cubes);
    if (try_merge(cubes, box, size, /*emit_failures=*/false)) return true;
    // Its two layers alone (2 × 2 × 1): thinner along z, where slices are often thicker;
    // where a layer fails, its two rows (2 × 1 × 1); where a row fails, its cubes alone.
    // A leaf one cube thick along an axis (dims, or the lattice's end) is not split along
    // it: its one half would be the leaf again.
    std::array<int, 2> axes{};
    int count = 0;
    for (int axis : {2, 1}) {
      if (box.hi[axis] - box.lo[axis] == 2) axes[count++] = axis;
    }
    if (count == 0) {
      try_single_cubes(cubes);
    } else {
      try_halves(cubes, box, std::span(axes).first(count));
    }
    return false;
  }
  const Dims half = children_of(dims, spacing_);
  // Stable partition into the eight octants, in scan order (z, then y, then x).
  std::array<std::size_t, 9> start{};
  auto octant = [&](std::uint32_t cube) {
    const BoundaryCube& c = piece_.cubes[cube];
    return (c.x >= box.lo[0] + half[0] ? 1 : 0) | (c.y >= box.lo[1] + half[1] ? 2 : 0) |
           (c.z >= box.lo[2] + half[2] ? 4 : 0);
  };
  scratch_order_.assign(cubes.begin(), cubes.end());
  scratch_octant_.resize(cubes.size());
  for (std::size_t i = 0; i < cubes.size(); ++i) {
    scratch_octant_[i] = static_cast<std::uint8_t>(octant(cubes[i]));
    ++start[scratch_octant_[i] + 1];
  }
  for (int k = 1; k < 9; ++k) start[k] += start[k - 1];
  {
    std::array<std::size_t, 8> fill;
    std::copy_n(start.begin(), 8, fill.begin());
    for (std::size_t i = 0; i < cubes.size(); ++i) {
      cubes[fill[scratch_octant_[i]]++] = scratch_order_[i];
    }
  }
  const std::size_t disks_before = store_.disks.size();
  bool all = true;
  for (int k = 0; k < 8; ++k) {
    if (start[k] == start[k + 1]) continue;
    Box child;
    for (int a = 0; a < 3; ++a) {
      const std::int32_t offset = (k >> a) & 1 ? half[a] : 0;
      child.lo[a] = box.lo[a] + offset;
      child.hi[a] = std::min(child.lo[a] + half[a], box.hi[a]);
    }
    all = test_block(cubes.subspan(start[k], start[k + 1] - start[k]), child, half) && all;
  }
  return all && try_replacing(box, size, disks_before);
}

// A box that failed as a whole, tried as its two halves along axes[0], each half that fails
// as its halves along axes[1], and so on; each of the last halves that fails, as its single
// cubes.
void BlockPass::try_halves(std::span<std::uint32_t> cubes, const Box& box,
                           std::span<const int> axes) {
  const bool last = axes.size() == 1;
  for (const auto& [part, part_box] : halves(cubes, box, axes[0])) {
    if (part.empty()) continue;
    if (one_cube(part_box)) {  // tried once, as its cube alone
      try_single_cubes(part);
      continue;
    }
    if (try_merge(part, part_box, 1, /*emit_failures=*/false)) continue;
    if (last) {
      try_single_cubes(part);
    } else {
      try_halves(part, part_box, axes.subspan(1));
    }
  }
}

// Each cube alone, as a box of one cube: a passing polygon gets no fewer triangles, but step
// 3 re-triangulates it for shape (best ears, flips) where marching cubes' table fans it; what
// fails keeps marching cubes' triangles. Returns whether every component of every cube passed.
bool BlockPass::try_single_cubes(std::span<std::uint32_t> cubes) {
  bool all = true;
  for (std::size_t i = 0; i < cubes.size(); ++i) {
    const BoundaryCube& cube = piece_.cubes[cubes[i]];
    Box one;
    one.lo = {cube.x, cube.y, cube.z};
    one.hi = {cube.x + 1, cube.y + 1, cube.z + 1};
    all = try_merge(cubes.subspan(i, 1), one, 1, /*emit_failures=*/true) && all;
  }
  return all;
}

// The box's marching-cubes triangles through the disk test; each passing component is
// recorded as a disk. Returns whether every component passed; with emit_failures the others
// keep their marching-cubes triangles (emitted now), else nothing is recorded unless all pass.
bool BlockPass::try_merge(std::span<const std::uint32_t> cubes, const Box& box,
                          std::int32_t size, bool emit_failures) {
  runs_.clear();
  std::size_t triangles = 0;
  for (std::uint32_t cube : cubes) {
    runs_.push_back(piece_.triangles_of(cube));
    triangles += runs_.back().end - runs_.back().first;
  }
  // A box of one connected piece (most) is tested without a union-find, and rejected before
  // its vertices are numbered when it is not flat (most that fail).
  const bool all = one_connected_surface(piece_.cubes, cubes, box)
                       ? test_.test_one_piece(runs_, box, stats_)
                       : test_.test_triangles(runs_, box, stats_);
  stats_.tested_triangles += triangles;
  if (!all) stats_.tested_triangles_failed += triangles;
  if (all || emit_failures) test_.record(box, size, store_, kept_);
  return all;
}

// The parts of the block were recorded as store_.disks[disks_before, end) and every one
// merged: tries the block as a whole, whose disks then replace theirs. Returns true either
// way (its cubes all belong to merged disks).
bool BlockPass::try_replacing(const Box& box, std::int32_t size, std::size_t disks_before) {
  if (store_.disks.size() == disks_before) return true;
  std::size_t loop_vertices = 0;
  for (std::size_t p = disks_before; p < store_.disks.size(); ++p) {
    loop_vertices += store_.disks[p].loop_size;
  }
  stats_.tested_loop_vertices += loop_vertices;
  if (!test_.test_parts(store_, disks_before, box, size, stats_, composed_)) {
    stats_.tested_loop_vertices_failed += loop_vertices;
    return true;
  }
  // The parts are kept, by component, for the composed disks to fall back to.
  for (std::uint32_t i = 0; i < composed_.disks.size(); ++i) {
    MergedDisk& composed = composed_.disks[i];
    composed.parts_first = static_cast<std::uint32_t>(store_.parts.size());
    for (std::size_t p = disks_before; p < store_.disks.size(); ++p) {
      if (composed_.part_component[p - disks_before] != i) continue;
      const MergedDisk& part = store_.disks[p];
      RetiredPart retired;
      retired.box = part.box;
      // Its triangles stay where the composed disk has them, from this offset on.
      retired.triangles_offset = composed_.part_offset[p - disks_before];
      retired.face_count = part.face_count;
      retired.parts_first = part.parts_first;
      retired.parts_count = part.parts_count;
      retired.size = part.size;
      store_.parts.push_back(retired);
    }
    composed.parts_count = static_cast<std::uint32_t>(store_.parts.size()) - composed.parts_first;
  }
  // The block's disks replace its parts at the end of each array (one disk's triangles, its
  // parts' in their order, are where they are already).
  const MergedDisk& first = store_.disks[disks_before];
  const std::uint32_t triangles_base = first.triangles_first;
  store_.loops.resize(first.loop_first);
  if (!composed_.in_place) {
    store_.triangles.resize(first.triangles_first);
    store_.areas.resize(first.triangles_first);
  }
  store_.vertices.resize(first.vertices_first);
  store_.disks.resize(disks_before);
  for (MergedDisk disk : composed_.disks) {
    disk.loop_first += static_cast<std::uint32_t>(store_.loops.size());
    disk.triangles_first += composed_.in_place
                                ? triangles_base
                                : static_cast<std::uint32_t>(store_.triangles.size());
    disk.vertices_first += static_cast<std::uint32_t>(store_.vertices.size());
    store_.disks.push_back(disk);
  }
  store_.loops.insert(store_.loops.end(), composed_.loops.begin(), composed_.loops.end());
  if (!composed_.in_place) {
    store_.triangles.insert(store_.triangles.end(), composed_.triangles.begin(),
                            composed_.triangles.end());
    store_.areas.insert(store_.areas.end(), composed_.areas.begin(), composed_.areas.end());
  }
  store_.vertices.insert(store_.vertices.end(), composed_.vertices.begin(),
                         composed_.vertices.end());
  return true;
}

}  // namespace

void test_blocks(const PieceSurface& piece, const Box& lattice, const Dims& block,
                 const std::array<double, 3>& spacing, DiskTest& test, DiskStore& store,
                 std::vector<Triangle>& kept, MergeStats& stats, std::size_t first_cube) {
  BlockPass(piece, spacing, test, store, kept, stats).run(lattice, block, first_cube);
}

}  // namespace typemerge::core::merge
