// Step 2 of type merging (type_merging.h): loop vertices inside a face that the boxes of
// exactly two merged disks share are thinned away where both loops can do without them.
//
// The bound: both disks lie in slabs no wider than `band` along their normals, and the chord
// that replaces a thinned polyline lies within δ of it both ways in the face (Douglas–Peucker
// with tolerance δ; the polyline joins the chord's ends in the plane of the face), so a point
// of either disk and the nearest point of its replacement differ by at most δ across and band
// along the normal: with δ = sqrt(ε² − band²) in voxels, within ε (in millimetres, where the
// two need not stay orthogonal, δ = (ε − band) / σ: tolerance.h). A shortcut never runs along a lattice
// line (a box edge or a cube edge, which other boxes share: it could duplicate their edge),
// and the two disks drop the same vertices, so the face's polyline stays one edge chain that
// both sides use.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/huge_pages.h"
#include "core/merge/disk_store.h"
#include "core/merge/geometry.h"
#include "core/merge/tolerance.h"
#include "core/type_merging.h"

namespace typemerge::core::merge {

// Per piece vertex, what thinning decided (step 3 gives removed vertices back).
enum VertexState : std::uint8_t { kOpen = 0, kRemoved = 1, kKept = 2 };

// Which disks' loops pass through each vertex (the first two, and how many), for the disks
// in the store when it is made.
class LoopOwners {
 public:
  // Its per-vertex arrays, which a caller can keep from piece to piece (their pages mapped
  // once).
  struct Arrays {
    detail::HugePageVector<std::array<std::uint32_t, 2>> disks;
    detail::HugePageVector<std::uint8_t> count;
    // Bit k: the vertex lies inside one face (on no edge) of disks[k]'s box.
    detail::HugePageVector<std::uint8_t> inside_face;
  };

  // Written into `arrays` (emptied first), which must outlive it.
  LoopOwners(std::span<const Position> positions, const DiskStore& store, Arrays& arrays);
  LoopOwners(const LoopOwners&) = delete;
  LoopOwners& operator=(const LoopOwners&) = delete;
  // The other disk when v lies inside a face shared by disk `self` and exactly one other:
  // the loops of exactly two disks pass through v, and v is inside a face (on no edge) of
  // both boxes, so the four cubes around v's lattice edge are theirs. Else kNone.
  std::uint32_t partner(VertexId v, std::uint32_t self) const;

 private:
  std::span<const Position> positions_;
  const DiskStore& store_;
  const detail::HugePageVector<std::array<std::uint32_t, 2>>& disks_;
  const detail::HugePageVector<std::uint8_t>& count_;
  const detail::HugePageVector<std::uint8_t>& inside_face_;
};

// Whether two positions lie on one lattice line (same edge axis, same other coordinates).
bool on_one_lattice_line(const Position& p, const Position& q);

// Douglas–Peucker on the polyline `run` (its ends kept): marks its inner vertices kRemoved in
// `state` where a shortcut passes within `tolerance` of them and does not run along a lattice
// line, else marks the farthest kKept and recurses on both sides. Returns how many it removed.
// Every removed vertex lies within `tolerance` of the chord that replaces it.
std::size_t thin_polyline(std::span<const Position> positions, std::span<const VertexId> run,
                          double tolerance, std::span<std::uint8_t> state);

// Thins every disk's loop where it runs through faces shared with exactly one other disk, by
// runs of one partner between vertices that stay; writes kRemoved / kKept into `state` (one
// per piece vertex, kOpen before) and counts stats.face_vertices_removed.
void thin_shared_faces(std::span<const Position> positions, const DiskStore& store,
                       const LoopOwners& owners, const Tolerance& tolerance,
                       std::vector<std::uint8_t>& state, MergeStats& stats);

}  // namespace typemerge::core::merge
