#include "core/merge/disk_test.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace typemerge::core::merge {

// The components of the local vertices (the table's union-find), numbered in order of their
// first vertex, with their vertex and loop-edge counts and a loop vertex each.
void DiskTest::number_components() {
  components_.clear();
  const std::uint32_t count = table_.count();
  component_of_.resize(count);
  if (table_.one_set()) {  // most boxes: no find needed
    std::fill(component_of_.begin(), component_of_.end(), 0u);
    components_.emplace_back();
  } else {
    for (std::uint32_t v = 0; v < count; ++v) {
      const std::uint32_t root = table_.find(v);
      if (root == v) {
        component_of_[v] = static_cast<std::uint32_t>(components_.size());
        components_.emplace_back();
      } else {
        component_of_[v] = component_of_[root];
      }
    }
  }
  for (std::uint32_t v = 0; v < count; ++v) {
    Component& c = components_[component_of_[v]];
    ++c.vertices;
    if (table_.next(v) != kNone) {
      ++c.loop_edges;
      c.loop_start = v;
    }
  }
}

// Appends c's loop (from c.loop_start along the table's loop edges) to `loops` at
// c.loop_first and returns whether it is simple projected along c's normal.
bool DiskTest::append_simple_loop(Component& c, const Box& box, std::vector<VertexId>& loops) {
  c.loop_first = static_cast<std::uint32_t>(loops.size());
  table_.append_loop(c.loop_start, loops);
  return outline_.is_simple(std::span(loops).subspan(c.loop_first), positions_, box, c.normal);
}

// The summed area vector kept as c.area, c.normal made unit; false when it is zero (the
// component faces no one way).
bool DiskTest::normalise(Component& c) {
  c.area = c.normal;
  const double length = std::sqrt(dot(c.normal, c.normal));
  if (!(length > 0.0)) return false;
  for (double& x : c.normal) x /= length;
  return true;
}

// Euler characteristic 1 (every edge not on the loop has a triangle on each side) and one
// loop of at least three edges.
bool DiskTest::one_disk(const Component& c) const {
  const std::size_t half_edges = 3 * c.faces + c.loop_edges;
  const auto euler = static_cast<std::int64_t>(c.vertices) -
                     static_cast<std::int64_t>(half_edges / 2) +
                     static_cast<std::int64_t>(c.faces);
  return half_edges % 2 == 0 && euler == 1 && c.loop_edges >= 3 &&
         table_.loop_closes(c.loop_start, c.loop_edges);
}

bool DiskTest::test_triangles(std::span<const TriangleRun> runs, const Box& box,
                              MergeStats& stats) {
  runs_ = runs;
  pinched_ = false;
  components_.clear();
  const FaceTest faces(box);
  std::size_t corners = 0;
  for (const TriangleRun& run : runs) corners += 3 * std::size_t{run.end - run.first};
  table_.start(corners);
  local_triangles_.clear();
  for (const TriangleRun& run : runs) {
    for (std::uint32_t id = run.first; id < run.end; ++id) {
      const Triangle& t = triangles_[id];
      LocalTriangle local;
      local.id = id;
      for (int k = 0; k < 3; ++k) local.corner[k] = table_.add_with_position(t[k], faces);
      table_.unite(local.corner[0], local.corner[1], local.corner[2]);
      if (table_.mark_loop_edges(local.corner)) {
        ++stats.rejected_topology;
        pinched_ = true;
        components_.clear();
        return false;
      }
      const P3& p0 = table_.position(local.corner[0]);
      local.area = cross(sub(table_.position(local.corner[1]), p0),
                         sub(table_.position(local.corner[2]), p0));
      local_triangles_.push_back(local);
    }
  }
  number_components();
  for (const LocalTriangle& t : local_triangles_) {
    Component& c = components_[component_of_[t.corner[0]]];
    ++c.faces;
    for (int a = 0; a < 3; ++a) c.normal[a] += t.area[a];
  }
  // Per component: one disk (Euler characteristic 1, one loop), facing one way, flat.
  for (Component& c : components_) {
    if (!one_disk(c)) {
      c.verdict = DiskVerdict::kTopology;
      ++stats.rejected_topology;
      continue;
    }
    if (!normalise(c)) {
      c.verdict = DiskVerdict::kFacing;
      ++stats.rejected_facing;
      continue;
    }
  }
  for (const LocalTriangle& t : local_triangles_) {
    Component& c = components_[component_of_[t.corner[0]]];
    if (c.verdict == DiskVerdict::kDisk && !(dot(t.area, c.normal) > 0.0)) {
      c.verdict = DiskVerdict::kFacing;
      ++stats.rejected_facing;
    }
  }
  for (std::uint32_t v = 0; v < table_.count(); ++v) {
    Component& c = components_[component_of_[v]];
    if (c.verdict != DiskVerdict::kDisk) continue;
    const double h = dot(table_.position(v), c.normal);
    c.low = std::min(c.low, h);
    c.high = std::max(c.high, h);
  }
  for (Component& c : components_) {
    if (c.verdict == DiskVerdict::kDisk &&
        tolerance_.span(c.high - c.low, c.normal) > tolerance_.epsilon()) {
      c.verdict = DiskVerdict::kFlatness;
      ++stats.rejected_flatness;
    }
  }
  // Separation: a disk whose slab does not leave some other component on one side stays.
  if (components_.size() > 1) {
    for (std::uint32_t i = 0; i < components_.size(); ++i) {
      Component& c = components_[i];
      if (c.verdict != DiskVerdict::kDisk) continue;
      // Per other component: 1 = all its vertices above c's slab, 2 = all below.
      separated_.assign(components_.size(), 3);
      for (std::uint32_t v = 0; v < table_.count(); ++v) {
        const std::uint32_t j = component_of_[v];
        if (j == i) continue;
        const double h = dot(table_.position(v), c.normal);
        if (!(h > c.high)) separated_[j] &= ~1u;
        if (!(h < c.low)) separated_[j] &= ~2u;
      }
      for (std::uint32_t j = 0; j < components_.size(); ++j) {
        if (j != i && separated_[j] == 0) {
          c.verdict = DiskVerdict::kSeparation;
          ++stats.rejected_separation;
          break;
        }
      }
    }
  }
  loop_.clear();
  bool all = true;
  for (Component& c : components_) {
    if (c.verdict != DiskVerdict::kDisk) {
      all = false;
      continue;
    }
    if (!append_simple_loop(c, box, loop_)) {
      c.verdict = DiskVerdict::kOutline;
      all = false;
      ++stats.rejected_outline;
    }
  }
  return all;
}

bool DiskTest::test_one_piece(std::span<const TriangleRun> runs, const Box& box,
                              MergeStats& stats) {
  runs_ = runs;
  components_.clear();
  local_triangles_.clear();
  // The area vectors and their sum in test_triangles' order (the same normal, bit for bit),
  // from the piece's positions (the table holds the same doubles).
  Component c;
  for (const TriangleRun& run : runs) {
    for (std::uint32_t id = run.first; id < run.end; ++id) {
      const Triangle& t = triangles_[id];
      LocalTriangle local;
      local.id = id;
      local.area = area_vector(positions_, t);
      for (int a = 0; a < 3; ++a) c.normal[a] += local.area[a];
      local_triangles_.push_back(local);
    }
  }
  // Facing and flatness as test_triangles judges them; a box failing either fails whatever
  // its topology, so the verdict is the same (the reason counted may differ).
  pinched_ = true;
  if (!normalise(c)) {
    ++stats.rejected_facing;
    return false;
  }
  for (const LocalTriangle& t : local_triangles_) {
    if (!(dot(t.area, c.normal) > 0.0)) {
      ++stats.rejected_facing;
      return false;
    }
  }
  // Over every corner, each vertex as often as it is one: the same extremes as over the
  // vertices.
  for (const LocalTriangle& t : local_triangles_) {
    for (VertexId v : triangles_[t.id]) {
      const double h = dot(to_double(positions_[v]), c.normal);
      c.low = std::min(c.low, h);
      c.high = std::max(c.high, h);
    }
  }
  if (tolerance_.span(c.high - c.low, c.normal) > tolerance_.epsilon()) {
    ++stats.rejected_flatness;
    return false;
  }
  // Its vertices and loop edges, as test_triangles numbers them.
  const FaceTest faces(box);
  table_.start(3 * local_triangles_.size());
  for (LocalTriangle& local : local_triangles_) {
    const Triangle& t = triangles_[local.id];
    for (int k = 0; k < 3; ++k) local.corner[k] = table_.add(t[k], faces);
    if (table_.mark_loop_edges(local.corner)) {
      ++stats.rejected_topology;
      return false;
    }
  }
  pinched_ = false;
  c.faces = local_triangles_.size();
  c.vertices = table_.count();
  for (std::uint32_t v = 0; v < table_.count(); ++v) {
    if (table_.next(v) != kNone) {
      ++c.loop_edges;
      c.loop_start = v;
    }
  }
  component_of_.assign(table_.count(), 0u);
  loop_.clear();
  if (!one_disk(c)) {
    c.verdict = DiskVerdict::kTopology;
    ++stats.rejected_topology;
  } else if (!append_simple_loop(c, box, loop_)) {
    c.verdict = DiskVerdict::kOutline;
    ++stats.rejected_outline;
  }
  components_.push_back(c);
  return c.verdict == DiskVerdict::kDisk;
}

void DiskTest::record(const Box& box, std::int32_t size, DiskStore& store,
                      std::vector<Triangle>& kept) {
  if (pinched_) {
    for (const TriangleRun& run : runs_) {
      for (std::uint32_t id = run.first; id < run.end; ++id) kept.push_back(triangles_[id]);
    }
    return;
  }
  bool any_kept = false;
  for (Component& c : components_) {
    if (c.verdict != DiskVerdict::kDisk) {
      any_kept = true;
      continue;
    }
    MergedDisk disk;
    disk.box = box;
    disk.normal = c.normal;
    disk.area = c.area;
    disk.band = tolerance_.span(c.high - c.low, c.normal);
    disk.loop_first = static_cast<std::uint32_t>(store.loops.size());
    disk.loop_size = static_cast<std::uint32_t>(c.loop_edges);
    disk.face_count = static_cast<std::uint32_t>(c.faces);
    disk.size = size;
    store.loops.insert(store.loops.end(), loop_.begin() + c.loop_first,
                       loop_.begin() + c.loop_first + c.loop_edges);
    c.disk = static_cast<std::uint32_t>(store.disks.size());
    store.disks.push_back(disk);
  }
  for (std::size_t k = 0; any_kept && k < local_triangles_.size(); ++k) {
    const LocalTriangle& t = local_triangles_[k];
    if (components_[component_of_[t.corner[0]]].verdict != DiskVerdict::kDisk) {
      kept.push_back(triangles_[t.id]);
    }
  }
  // Each disk's triangles (for its demotion, and with its vertices for the blocks it is a
  // part of; disks are in component order).
  for (std::uint32_t i = 0; i < components_.size(); ++i) {
    const Component& c = components_[i];
    if (c.verdict != DiskVerdict::kDisk) continue;
    MergedDisk& disk = store.disks[c.disk];
    disk.triangles_first = static_cast<std::uint32_t>(store.triangles.size());
    for (const LocalTriangle& t : local_triangles_) {
      if (component_of_[t.corner[0]] == i) {
        store.triangles.push_back(t.id);
        store.areas.push_back({static_cast<float>(t.area[0]), static_cast<float>(t.area[1]),
                               static_cast<float>(t.area[2])});
      }
    }
    disk.vertices_first = static_cast<std::uint32_t>(store.vertices.size());
    for (std::uint32_t v = 0; v < table_.count(); ++v) {
      if (component_of_[v] == i) store.vertices.push_back(table_.vertex(v));
    }
    disk.vertex_count = static_cast<std::uint32_t>(store.vertices.size()) - disk.vertices_first;
  }
}

bool DiskTest::test_parts(const DiskStore& store, std::size_t first_part, const Box& box,
                          std::int32_t size, MergeStats& stats, ComposedBlock& out) {
  const auto parts = static_cast<std::uint32_t>(store.disks.size() - first_part);
  std::size_t loop_vertices = 0;
  for (std::uint32_t p = 0; p < parts; ++p) loop_vertices += store.disks[first_part + p].loop_size;
  table_.start(loop_vertices);
  const FaceTest faces(box);
  out.part_component.resize(parts);
  out.part_offset.resize(parts);
  for (std::uint32_t p = 0; p < parts; ++p) {
    const MergedDisk& part = store.disks[first_part + p];
    const VertexId* loop = store.loops.data() + part.loop_first;
    std::uint32_t previous = table_.add(loop[part.loop_size - 1], faces);
    for (std::uint32_t k = 0; k < part.loop_size; ++k) {
      const std::uint32_t a = previous;
      const std::uint32_t b = table_.add(loop[k], faces);
      previous = b;
      table_.unite(a, b);
      if ((table_.mask(a) & table_.mask(b)) == 0) continue;  // on a face two parts share
      // On the block's loop; two leaving one vertex: pinched, no disk.
      if (table_.next(a) != kNone) {
        ++stats.rejected_topology;
        return false;
      }
      table_.set_next(a, b);
    }
  }
  number_components();  // in order of their first loop vertex
  // Per component: its parts (F), inner half-edges (2 per inner edge), area.
  for (std::uint32_t p = 0; p < parts; ++p) {
    const MergedDisk& part = store.disks[first_part + p];
    const std::uint32_t id = component_of_[table_.local(store.loops[part.loop_first])];
    out.part_component[p] = id;
    Component& c = components_[id];
    ++c.faces;
    c.inner_half_edges += part.loop_size;
    for (int a = 0; a < 3; ++a) c.normal[a] += part.area[a];
  }
  for (Component& c : components_) {
    c.inner_half_edges -= c.loop_edges;
    const auto euler = static_cast<std::int64_t>(c.vertices) -
                       static_cast<std::int64_t>(c.loop_edges + c.inner_half_edges / 2) +
                       static_cast<std::int64_t>(c.faces);
    if (c.inner_half_edges % 2 != 0 || euler != 1 || c.loop_edges < 3 ||
        !table_.loop_closes(c.loop_start, c.loop_edges)) {
      ++stats.rejected_topology;
      return false;
    }
    if (!normalise(c)) {
      ++stats.rejected_facing;
      return false;
    }
  }
  // Facing, then flatness, over the parts' triangles and vertices.
  for (std::uint32_t p = 0; p < parts; ++p) {
    const MergedDisk& part = store.disks[first_part + p];
    Component& c = components_[out.part_component[p]];
    const std::array<float, 3>* area = store.areas.data() + part.triangles_first;
    for (std::uint32_t t = 0; t < part.face_count; ++t) {
      const P3 a = to_double(area[t]);
      const double along = dot(a, c.normal);
      if (!(along > 0.0 && along * along > 1e-12 * dot(a, a))) {
        ++stats.rejected_facing;
        return false;
      }
    }
    const VertexId* vertex = store.vertices.data() + part.vertices_first;
    for (std::uint32_t k = 0; k < part.vertex_count; ++k) {
      const double h = dot(to_double(positions_[vertex[k]]), c.normal);
      c.low = std::min(c.low, h);
      c.high = std::max(c.high, h);
    }
  }
  for (const Component& c : components_) {
    if (tolerance_.span(c.high - c.low, c.normal) > tolerance_.epsilon()) {
      ++stats.rejected_flatness;
      return false;
    }
  }
  if (components_.size() > 1) {
    for (std::uint32_t i = 0; i < components_.size(); ++i) {
      const Component& c = components_[i];
      // Per other component: 1 = all its vertices above c's slab, 2 = all below.
      separated_.assign(components_.size(), 3);
      for (std::uint32_t p = 0; p < parts; ++p) {
        const std::uint32_t j = out.part_component[p];
        if (j == i) continue;
        const MergedDisk& part = store.disks[first_part + p];
        const VertexId* vertex = store.vertices.data() + part.vertices_first;
        for (std::uint32_t k = 0; k < part.vertex_count; ++k) {
          const double h = dot(to_double(positions_[vertex[k]]), c.normal);
          if (!(h > c.high)) separated_[j] &= ~1u;
          if (!(h < c.low)) separated_[j] &= ~2u;
        }
      }
      for (std::uint32_t j = 0; j < components_.size(); ++j) {
        if (j != i && separated_[j] == 0) {
          ++stats.rejected_separation;
          return false;
        }
      }
    }
  }
  out.loops.clear();
  for (Component& c : components_) {
    if (!append_simple_loop(c, box, out.loops)) {
      ++stats.rejected_outline;
      return false;
    }
  }
  // Every component passed: the block's disks, their triangles and vertices gathered from
  // their parts (each vertex once).
  out.disks.clear();
  out.triangles.clear();
  out.areas.clear();
  out.vertices.clear();
  out.in_place = components_.size() == 1;
  std::uint32_t in_place_offset = 0;
  table_.new_visit();
  for (std::uint32_t i = 0; i < components_.size(); ++i) {
    const Component& c = components_[i];
    MergedDisk disk;
    disk.box = box;
    disk.normal = c.normal;
    disk.area = c.area;
    disk.band = tolerance_.span(c.high - c.low, c.normal);
    disk.loop_first = c.loop_first;
    disk.loop_size = static_cast<std::uint32_t>(c.loop_edges);
    disk.triangles_first = static_cast<std::uint32_t>(out.triangles.size());
    disk.vertices_first = static_cast<std::uint32_t>(out.vertices.size());
    disk.size = size;
    for (std::uint32_t p = 0; p < parts; ++p) {
      if (out.part_component[p] != i) continue;
      const MergedDisk& part = store.disks[first_part + p];
      if (out.in_place) {
        out.part_offset[p] = in_place_offset;
        in_place_offset += part.face_count;
      } else {
        const auto first = static_cast<std::ptrdiff_t>(part.triangles_first);
        const auto end = first + static_cast<std::ptrdiff_t>(part.face_count);
        out.part_offset[p] = static_cast<std::uint32_t>(out.triangles.size()) - disk.triangles_first;
        out.triangles.insert(out.triangles.end(), store.triangles.begin() + first,
                             store.triangles.begin() + end);
        out.areas.insert(out.areas.end(), store.areas.begin() + first, store.areas.begin() + end);
      }
      for (std::uint32_t k = 0; k < part.vertex_count; ++k) {
        const VertexId v = store.vertices[part.vertices_first + k];
        if (!table_.seen(v)) out.vertices.push_back(v);
      }
    }
    disk.face_count = out.in_place
                          ? in_place_offset
                          : static_cast<std::uint32_t>(out.triangles.size()) - disk.triangles_first;
    disk.vertex_count = static_cast<std::uint32_t>(out.vertices.size()) - disk.vertices_first;
    out.disks.push_back(disk);
  }
  return true;
}

}  // namespace typemerge::core::merge
