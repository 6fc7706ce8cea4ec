#include "core/merge/loop_thinning.h"

#include <algorithm>
#include <cmath>

#include "core/mesh_distance.h"

namespace typemerge::core::merge {

namespace {

// Whether face bits say one face and no edge (exactly one bit).
bool inside_one_face(unsigned mask) { return mask != 0 && (mask & (mask - 1)) == 0; }

}  // namespace

// Where a loop vertex lies on its owners' boxes is found here, box by box, so that partner()
// reads no other disk (a random read of the other disk's box was most of its time).
LoopOwners::LoopOwners(std::span<const Position> positions, const DiskStore& store,
                       Arrays& arrays)
    : positions_(positions),
      store_(store),
      disks_(arrays.disks),
      count_(arrays.count),
      inside_face_(arrays.inside_face) {
  arrays.disks.assign(positions.size(), {kNone, kNone});
  arrays.count.assign(positions.size(), 0);
  arrays.inside_face.assign(positions.size(), 0);
  for (std::uint32_t id = 0; id < store.disks.size(); ++id) {
    const FaceTest faces(store.disks[id].box);
    for (VertexId v : store.loop_of(store.disks[id])) {
      std::uint8_t& count = arrays.count[v];
      if (count < 2) {
        arrays.disks[v][count] = id;
        if (inside_one_face(faces.mask(positions[v]))) {
          arrays.inside_face[v] = static_cast<std::uint8_t>(arrays.inside_face[v] | 1u << count);
        }
      }
      if (count < 255) ++count;
    }
  }
}

std::uint32_t LoopOwners::partner(VertexId v, std::uint32_t self) const {
  if (count_[v] != 2) return kNone;
  const unsigned slot = disks_[v][0] == self ? 1 : 0;  // the other's
  if (((inside_face_[v] >> slot) & 1u) == 0) return kNone;
  // Self's box from the store (a part made after this table was is no owner here).
  if (!inside_one_face(FaceTest(store_.disks[self].box).mask(positions_[v]))) return kNone;
  return disks_[v][slot];
}

bool on_one_lattice_line(const Position& p, const Position& q) {
  int same = 0;
  for (int a = 0; a < 3; ++a) {
    if (p[a] == q[a] && p[a] == std::floor(p[a])) ++same;
  }
  return same >= 2;
}

namespace {

std::size_t thin_run(std::span<const Position> positions, std::span<const VertexId> run,
                     std::size_t first, std::size_t last, double tolerance,
                     std::span<std::uint8_t> state) {
  if (last <= first + 1) return 0;
  const P3 a = to_double(positions[run[first]]);
  const P3 b = to_double(positions[run[last]]);
  std::size_t far = first;
  double far_distance = -1.0;
  for (std::size_t k = first + 1; k < last; ++k) {
    const double d = std::sqrt(
        detail::point_segment_distance_squared(to_double(positions[run[k]]), a, b));
    if (d > far_distance) {
      far_distance = d;
      far = k;
    }
  }
  if (far_distance <= tolerance && !on_one_lattice_line(positions[run[first]], positions[run[last]])) {
    for (std::size_t k = first + 1; k < last; ++k) state[run[k]] = kRemoved;
    return last - first - 1;
  }
  state[run[far]] = kKept;
  return thin_run(positions, run, first, far, tolerance, state) +
         thin_run(positions, run, far, last, tolerance, state);
}

}  // namespace

std::size_t thin_polyline(std::span<const Position> positions, std::span<const VertexId> run,
                          double tolerance, std::span<std::uint8_t> state) {
  if (run.size() < 2) return 0;
  return thin_run(positions, run, 0, run.size() - 1, tolerance, state);
}

void thin_shared_faces(std::span<const Position> positions, const DiskStore& store,
                       const LoopOwners& owners, const Tolerance& tolerance,
                       std::vector<std::uint8_t>& state, MergeStats& stats) {
  std::vector<std::uint32_t> partners;
  std::vector<VertexId> run;
  // The disks' bands side by side: a partner's is read at random, and a disk's record is
  // large (perf put most of this pass's time on reading the band from it).
  std::vector<double> bands(store.disks.size());
  for (std::size_t id = 0; id < bands.size(); ++id) bands[id] = store.disks[id].band;
  for (std::uint32_t id = 0; id < store.disks.size(); ++id) {
    const MergedDisk& disk = store.disks[id];
    const std::span<const VertexId> loop = store.loop_of(disk);
    const std::size_t n = loop.size();
    partners.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      partners[k] = state[loop[k]] == kOpen ? owners.partner(loop[k], id) : kNone;
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
        for (std::size_t r = 1; r < run.size(); ++r) state[run[r]] = kKept;
      } else {
        run.push_back(loop[end]);
        // The header's bound.
        const double offset = tolerance.thinning_tolerance(bands[id], bands[other]);
        stats.face_vertices_removed += thin_polyline(positions, run, offset, state);
        for (std::size_t r = 1; r + 1 < run.size(); ++r) {
          if (state[run[r]] == kOpen) state[run[r]] = kKept;
        }
      }
      k = j;
    }
  }
}

}  // namespace typemerge::core::merge
