#include "core/merge/disk_triangulation.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <span>

#include "core/mesh_checks.h"

namespace typemerge::core::merge {
namespace {

class DiskTriangulation {
 public:
  DiskTriangulation(const PieceSurface& piece, const std::array<Vec3, 3>& axes,
                    const LoopOwners& owners, DiskStore& store, std::vector<std::uint8_t>& state,
                    LocalTable& table, LoopTriangulator& triangulator, std::vector<Triangle>& made,
                    MergeStats& stats)
      : positions_(piece.mesh.positions),
        triangles_(piece.mesh.triangles),
        axes_(axes),
        owners_(owners),
        store_(store),
        state_(state),
        table_(table),
        triangulator_(triangulator),
        made_(made),
        stats_(stats) {
    made_.clear();
  }

  void run(std::vector<Triangle>& out);

 private:
  void restore_loop(const MergedDisk& disk, std::uint32_t id, std::vector<std::uint32_t>& again);
  void split_into_parts(std::uint32_t id, std::vector<std::uint32_t>& again);
  void rebuild_loop(MergedDisk& part);
  bool shape_as_good(const MergedDisk& disk) const;

  std::span<const Position> positions_;
  std::span<const Triangle> triangles_;
  const std::array<Vec3, 3>& axes_;
  const LoopOwners& owners_;
  DiskStore& store_;
  std::vector<std::uint8_t>& state_;
  LocalTable& table_;
  LoopTriangulator& triangulator_;
  std::vector<Triangle>& made_;  // the disks' new triangles
  MergeStats& stats_;
};

// Gives back every thinned vertex of the disk's loop; the other disk of each (the only other
// disk the vertex's loop passes through) must be triangulated again.
void DiskTriangulation::restore_loop(const MergedDisk& disk, std::uint32_t id,
                                     std::vector<std::uint32_t>& again) {
  for (VertexId v : store_.loop_of(disk)) {
    if (state_[v] != kRemoved) continue;
    state_[v] = kKept;
    ++stats_.face_vertices_restored;
    const std::uint32_t other = owners_.partner(v, id);
    if (other != kNone) again.push_back(other);
  }
}

void DiskTriangulation::run(std::vector<Triangle>& out) {
  std::vector<VertexId> loop;
  std::vector<std::uint32_t> todo(store_.disks.size());
  for (std::uint32_t id = 0; id < todo.size(); ++id) todo[id] = id;
  std::vector<std::uint32_t> again;
  while (!todo.empty()) {
    ++stats_.triangulation_passes;
    again.clear();
    for (std::uint32_t id : todo) {
      MergedDisk& disk = store_.disks[id];
      if (disk.demoted || disk.split) continue;
      const std::span<const VertexId> full = store_.loop_of(disk);
      loop.clear();
      for (VertexId v : full) {
        if (state_[v] != kRemoved) loop.push_back(v);
      }
      const std::size_t before = made_.size();
      const bool done = loop.size() - 2 <= disk.face_count &&
                        triangulator_.triangulate(loop, positions_, disk.box, disk.normal,
                                                  loop.size() != full.size(),
                                                  made_) == Triangulation::kDone &&
                        shape_as_good(disk);
      if (done) {
        disk.made_first = static_cast<std::uint32_t>(before);
        disk.made_count = static_cast<std::uint32_t>(made_.size() - before);
        continue;
      }
      made_.resize(before);
      if (loop.size() == full.size()) {
        // Not even the whole loop: the disk falls back to the disks it was composed of
        // (triangulated next), or, made of none, keeps its marching-cubes triangles.
        if (disk.parts_count > 0) {
          disk.split = true;
          ++stats_.blocks_split;
          split_into_parts(id, again);  // `disk` is not used after: the store grows
          continue;
        }
        disk.demoted = true;
        ++stats_.blocks_demoted;
      }
      restore_loop(disk, id, again);
      again.push_back(id);
    }
    std::sort(again.begin(), again.end());
    again.erase(std::unique(again.begin(), again.end()), again.end());
    todo.swap(again);
  }
  for (const MergedDisk& disk : store_.disks) {
    if (disk.split) continue;  // its parts are disks of their own
    if (disk.demoted) {
      for (std::uint32_t k = 0; k < disk.face_count; ++k) {
        out.push_back(triangles_[store_.triangles[disk.triangles_first + k]]);
      }
    } else {
      ++stats_.blocks_merged[static_cast<std::size_t>(
          std::countr_zero(static_cast<unsigned>(disk.size)))];
      out.insert(out.end(), made_.begin() + disk.made_first,
                 made_.begin() + disk.made_first + disk.made_count);
    }
  }
}

// Replaces disk `id`, whose whole loop could not be triangulated well, by its parts: they are
// appended to the store (their loops rebuilt; their triangles are the disk's, where they
// already are) and queued in `again`. Each passed every test on its own and its box lies in
// the disk's, so they are what the disk's block would have left had its own test failed,
// minus thinning (none of their vertices is thinned: those inside the disk's box never were,
// the disk's loop is whole). Parts of parts stay in the store for the parts to fall back to.
void DiskTriangulation::split_into_parts(std::uint32_t id, std::vector<std::uint32_t>& again) {
  const std::uint32_t first = store_.disks[id].parts_first;
  const std::uint32_t count = store_.disks[id].parts_count;
  for (std::uint32_t p = first; p < first + count; ++p) {
    const RetiredPart& retired = store_.parts[p];
    MergedDisk part;
    part.box = retired.box;
    part.triangles_first = store_.disks[id].triangles_first + retired.triangles_offset;
    part.face_count = retired.face_count;
    part.parts_first = retired.parts_first;
    part.parts_count = retired.parts_count;
    part.size = retired.size;
    rebuild_loop(part);
    again.push_back(static_cast<std::uint32_t>(store_.disks.size()));
    store_.disks.push_back(part);
  }
}

// A part's loop (appended to the store's loops) and normal, from its marching-cubes triangles
// as the disk test finds them: its edges on its box's faces, directed as their triangles have
// them, and the sum of their area vectors. (Summed in another order than when it passed, the
// normal may differ in its last bits; every triangle faced it with a margin of 1e-6 of its
// area, far above that, so the loop still projects one-to-one.)
void DiskTriangulation::rebuild_loop(MergedDisk& part) {
  const FaceTest faces(part.box);
  table_.start(3 * static_cast<std::size_t>(part.face_count));
  P3 area{0, 0, 0};
  for (std::uint32_t k = 0; k < part.face_count; ++k) {
    const Triangle& t = triangles_[store_.triangles[part.triangles_first + k]];
    std::array<std::uint32_t, 3> corner{};
    for (int c = 0; c < 3; ++c) corner[c] = table_.add(t[c], faces);
    table_.mark_loop_edges(corner);  // no pinch: the part passed the disk test
    const P3 a = area_vector(positions_, t);
    for (int c = 0; c < 3; ++c) area[c] += a[c];
  }
  std::uint32_t start = 0;
  while (table_.next(start) == kNone) ++start;  // a disk that passed has a loop
  part.loop_first = static_cast<std::uint32_t>(store_.loops.size());
  table_.append_loop(start, store_.loops);
  part.loop_size = static_cast<std::uint32_t>(store_.loops.size()) - part.loop_first;
  part.area = area;
  const double length = std::sqrt(dot(area, area));
  for (int c = 0; c < 3; ++c) part.normal[c] = area[c] / length;
}

// Whether the triangulation just made has no more caps and needles than the disk's
// marching-cubes triangles. A new triangle can be extreme only if its smallest angle is below
// 10° (a cap's other two angles sum to less), so the triangulator measures only those, and
// marching cubes' are measured only for a triangulation with one.
bool DiskTriangulation::shape_as_good(const MergedDisk& disk) const {
  const ExtremeAngles& made = triangulator_.extremes();
  if (made.above_170 == 0 && made.below_1 == 0) return true;
  ExtremeAngles old;
  for (std::uint32_t k = 0; k < disk.face_count; ++k) {
    const Triangle& t = triangles_[store_.triangles[disk.triangles_first + k]];
    old += extreme_angles_of(in_mm(positions_[t[0]], axes_), in_mm(positions_[t[1]], axes_),
                             in_mm(positions_[t[2]], axes_));
    if (made.above_170 <= old.above_170 && made.below_1 <= old.below_1) return true;
  }
  return false;
}

}  // namespace

void triangulate_disks(const PieceSurface& piece, const std::array<Vec3, 3>& axes,
                       const LoopOwners& owners, DiskStore& store,
                       std::vector<std::uint8_t>& state, LocalTable& table,
                       LoopTriangulator& triangulator, std::vector<Triangle>& made,
                       std::vector<Triangle>& out, MergeStats& stats) {
  DiskTriangulation(piece, axes, owners, store, state, table, triangulator, made, stats).run(out);
}

}  // namespace typemerge::core::merge
