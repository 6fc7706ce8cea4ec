// Step 3's core (type_merging.h): a disk's loop → triangles, in the projection along the
// disk's normal. A pure function of the loop, its vertices' positions, its box and the normal
// (the class only keeps scratch buffers between calls).
//
// Contract of triangulate(): the loop is counter-clockwise about n; on kDone it appends
// loop.size() − 2 triangles whose projections tile the projected loop (a planar
// triangulation, so no two cross), each counter-clockwise about n with a projected twice-area
// above kMinDoubleArea, and with no edge between two loop vertices on one face of the box
// (nor a triangle with all three corners on one face): so a new edge never lies on a box
// face, where a neighbouring box or cube could have it too. Otherwise nothing is appended.
// The shape rule: ears are clipped best smallest angle (in millimetres) first, then Lawson
// flips raise the smallest angle of each pair where the quad is convex and the new edge obeys
// the face rule; extremes() then counts the caps (an angle above 170°) and needles (below 1°)
// made, which step 3 compares with marching cubes' triangles of the disk. A loop of three or
// four vertices takes its own path (clip_triangle, clip_quad), whose triangles, their order and
// corners, and extremes are the general path's, bit for bit (checked against it on every such
// loop of the real series).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/merge/geometry.h"
#include "core/mesh_checks.h"
#include "core/volume.h"

namespace typemerge::core::merge {

enum class Triangulation { kDone, kNotSimple, kStuck };

class LoopTriangulator {
 public:
  // `axes`: one index step in millimetres along each axis (IndexToPatient::axes), where
  // shapes are judged (with 3 mm slices a triangle fine in index space can be a needle in mm).
  explicit LoopTriangulator(const std::array<Vec3, 3>& axes) : axes_(axes) {}

  // Whether the loop projected along n is simple and counter-clockwise (one-to-one: the
  // outline test of a disk).
  bool is_simple(std::span<const VertexId> loop, std::span<const Position> positions,
                 const Box& box, const P3& n);

  // Triangulates `loop` into `out` as above. check_outline: test first that the projected
  // loop is simple (kNotSimple if not; known for a loop that passed the disk test unthinned).
  Triangulation triangulate(std::span<const VertexId> loop, std::span<const Position> positions,
                            const Box& box, const P3& n, bool check_outline,
                            std::vector<Triangle>& out);

  // Caps and needles among the triangles of the last kDone.
  const ExtremeAngles& extremes() const { return made_extremes_; }

 private:
  void project(std::span<const VertexId> loop, std::span<const Position> positions,
               const Box& box, const P3& n, bool face_masks);
  bool star_shaped_from_centroid() const;
  bool flat_is_simple();
  double shape(std::uint32_t a, std::uint32_t b, std::uint32_t c) const;
  bool ear_valid(std::uint32_t i) const;
  bool clip_ears(std::span<const VertexId> loop, std::span<const Position> positions,
                 std::vector<Triangle>& out);
  bool clip_any();
  bool clip_triangle();
  bool clip_quad();
  static bool flip_raises(double before, double after);
  void flip_for_shape();

  std::array<Vec3, 3> axes_;
  std::vector<std::array<double, 2>> flat_;  // the projected loop
  std::vector<std::uint8_t> flat_masks_;      // its vertices' face bits on the box
  std::vector<P3> mm_;                        // the loop in patient millimetres, for shape()
  std::vector<std::array<double, 4>> edge_boxes_;  // flat_is_simple's scratch
  std::vector<double> ear_shape_;  // shape() of each triangle in ears_
  ExtremeAngles made_extremes_;    // caps and needles among them
  std::vector<std::uint32_t> edge_owner_;  // flip_for_shape's edge table, zero between loops
  std::vector<std::array<std::uint32_t, 3>> rejected_;  // and its rejected flips
  std::uint32_t flip_stamp_ = 0;
  std::vector<std::uint32_t> prev_;
  std::vector<std::uint32_t> succ_;
  std::vector<double> score_;
  std::vector<std::array<std::uint32_t, 3>> ears_;  // clipped triangles, by loop position
};

}  // namespace typemerge::core::merge
