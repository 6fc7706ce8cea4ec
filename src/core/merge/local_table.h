// A block's vertices numbered 0, 1, … in the order first seen, with their positions, their
// face bits on the block, one directed loop edge leaving each (or none) and a union-find over
// them: what the disk test and the rebuilding of a part's loop read a block's surface into.
// Reused from block to block: emptied by a new visit stamp, not cleared (local_vertex runs for
// every corner of every triangle tested; written by index, not push_back).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/merge/geometry.h"

namespace typemerge::core::merge {

class LocalTable {
 public:
  LocalTable() = default;
  // For the vertices of a piece, at `positions` (index space).
  explicit LocalTable(std::span<const Position> positions) { reset(positions); }

  // For another piece's vertices: as newly made, its arrays' capacity kept and room made for
  // `room` vertices (a thread merging piece after piece maps their pages once).
  void reset(std::span<const Position> positions, std::size_t room = 0) {
    positions_of_piece_ = positions;
    stamp_.reserve(room);
    local_.reserve(room);
    stamp_.assign(positions.size(), 0);
    local_.assign(positions.size(), 0);
    visit_ = 0;
    count_ = 0;
  }

  // For the same piece's vertices, more of them made since (stamps and ids kept; room as
  // reserved by reset, so the arrays do not move while there is room).
  void extend(std::span<const Position> positions) {
    positions_of_piece_ = positions;
    stamp_.resize(positions.size(), 0);
    local_.resize(positions.size(), 0);
  }

  // A new stamp for the piece's vertices: after it, seen() is false for every vertex.
  void new_visit() {
    if (++visit_ == 0) {
      std::fill(stamp_.begin(), stamp_.end(), 0);
      visit_ = 1;
    }
  }
  // Marks v seen in this visit; returns whether it was seen already.
  bool seen(VertexId v) {
    if (stamp_[v] == visit_) return true;
    stamp_[v] = visit_;
    return false;
  }

  // Empties the table (a new visit), with room for `capacity` vertices.
  void start(std::size_t capacity) {
    new_visit();
    count_ = 0;
    if (vertices_.size() < capacity) {
      vertices_.resize(capacity);
      positions_.resize(capacity);
      masks_.resize(capacity);
      next_.resize(capacity);
      parent_.resize(capacity);
    }
  }

  // Vertex v's local index, adding it (with its face bits on the box) when new; position()
  // is then unset (see add_with_position).
  std::uint32_t add(VertexId v, const FaceTest& faces) { return add_vertex<false>(v, faces); }
  // The same, position() set.
  std::uint32_t add_with_position(VertexId v, const FaceTest& faces) {
    return add_vertex<true>(v, faces);
  }
  // The local index of a vertex added in this visit.
  std::uint32_t local(VertexId v) const { return local_[v]; }

  std::uint32_t count() const { return count_; }
  VertexId vertex(std::uint32_t i) const { return vertices_[i]; }
  const P3& position(std::uint32_t i) const { return positions_[i]; }  // add_with_position's
  unsigned mask(std::uint32_t i) const { return masks_[i]; }
  std::uint32_t next(std::uint32_t i) const { return next_[i]; }
  void set_next(std::uint32_t i, std::uint32_t j) { next_[i] = j; }

  // Marks the edges of the triangle with these local corners that lie on a face of the box
  // as loop edges, directed as the triangle has them; returns whether one leaves a vertex that
  // has a loop edge already (two leaving one vertex pinch the surface there; next() is then
  // not to be read). Without a branch on whether an edge is on a face (a quarter of those
  // branches were mispredicted: cachegrind's branch simulation put them first in the merge).
  bool mark_loop_edges(const std::array<std::uint32_t, 3>& corner) {
    bool pinched = false;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = corner[k];
      const std::uint32_t b = corner[k == 2 ? 0 : k + 1];
      const bool on_face = (masks_[a] & masks_[b]) != 0;
      pinched |= on_face & (next_[a] != kNone);
      next_[a] = on_face ? b : next_[a];
    }
    return pinched;
  }

  std::uint32_t find(std::uint32_t v) {
    while (parent_[v] != v) {
      parent_[v] = parent_[parent_[v]];
      v = parent_[v];
    }
    return v;
  }
  // Each set's root is its smallest vertex.
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }
  void unite(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    a = find(a);
    b = find(b);
    c = find(c);
    const std::uint32_t root = std::min({a, b, c});
    parent_[a] = root;
    parent_[b] = root;
    parent_[c] = root;
  }
  // Whether the vertices form one set (vertex 0's; no other root).
  bool one_set() const {
    for (std::uint32_t v = 1; v < count_; ++v) {
      if (parent_[v] == v) return false;
    }
    return count_ > 0;
  }

  // Appends the loop of local vertices from `start` along next() to `loops` (as piece ids).
  template <typename Loops>  // a std::vector of VertexId, whatever its allocator
  void append_loop(std::uint32_t start, Loops& loops) const {
    std::uint32_t v = start;
    do {
      loops.push_back(vertices_[v]);
      v = next_[v];
    } while (v != start);
  }

  // Whether the loop edges from `start` close into one cycle of all `edges` of them.
  bool loop_closes(std::uint32_t start, std::size_t edges) const {
    std::size_t steps = 0;
    std::uint32_t v = start;
    do {
      v = next_[v];
      ++steps;
    } while (v != start && v != kNone && steps <= edges);
    return v == start && steps == edges;
  }

 private:
  template <bool kPosition>
  std::uint32_t add_vertex(VertexId v, const FaceTest& faces) {
    if (stamp_[v] != visit_) {
      stamp_[v] = visit_;
      const std::uint32_t i = count_++;
      local_[v] = i;
      vertices_[i] = v;
      const Position& p = positions_of_piece_[v];
      if constexpr (kPosition) positions_[i] = to_double(p);
      masks_[i] = static_cast<std::uint8_t>(faces.mask(p));
      next_[i] = kNone;
      parent_[i] = i;
    }
    return local_[v];
  }

  std::span<const Position> positions_of_piece_;
  std::vector<std::uint32_t> stamp_;  // per piece vertex: the visit that last saw it
  std::vector<std::uint32_t> local_;  // per piece vertex: its local index
  std::uint32_t visit_ = 0;
  std::uint32_t count_ = 0;
  std::vector<VertexId> vertices_;
  std::vector<P3> positions_;
  std::vector<std::uint8_t> masks_;
  std::vector<std::uint32_t> next_;
  std::vector<std::uint32_t> parent_;
};

}  // namespace typemerge::core::merge
