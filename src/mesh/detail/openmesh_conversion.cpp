#include "mesh/detail/openmesh_conversion.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <limits>
#include <numeric>
#include <unordered_set>
#include <utility>
#include <vector>

#include <OpenMesh/Core/System/omstream.hh>

#include "core/union_find.h"
#include "mesh/normals.h"

namespace typemerge::mesh::detail {
namespace {

using Triangle = std::array<std::uint32_t, 3>;

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{a} << 32) | b;
}

// Step 2: first come, first kept.
std::vector<Triangle> accept_manifold_edges(const core::TriangleMesh& mesh, ToOpenMesh& result) {
  std::vector<Triangle> accepted;
  accepted.reserve(mesh.triangles.size());
  std::unordered_set<std::uint64_t> directed;  // directed edges in use
  directed.reserve(mesh.triangles.size() * 3);
  for (const Triangle& t : mesh.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
      ++result.skipped_repeated_index;
      continue;
    }
    bool free = true;
    for (int k = 0; k < 3 && free; ++k) {
      const std::uint32_t a = t[k];
      const std::uint32_t b = t[(k + 1) % 3];
      // a→b taken means a flipped neighbour or a third face; b→a alone is the partner.
      if (directed.contains(edge_key(a, b))) free = false;
    }
    if (!free) {
      ++result.rejected_faces;
      continue;
    }
    for (int k = 0; k < 3; ++k) directed.insert(edge_key(t[k], t[(k + 1) % 3]));
    accepted.push_back(t);
  }
  return accepted;
}

using core::find_root;

// Step 3: group the corners at each vertex into fans (corners joined when their triangles
// share an edge at the vertex) and renumber the corners of every fan but the first to a new
// vertex, rewriting `triangles`. `copies` receives the source vertex of every new vertex.
void split_fans(std::vector<Triangle>& triangles, std::size_t vertex_count,
                std::vector<std::uint32_t>& copies) {
  // Corners (triangle · 3 + k) sorted by vertex.
  std::vector<std::uint32_t> offsets(vertex_count + 1, 0);
  for (const Triangle& t : triangles) {
    for (const std::uint32_t v : t) ++offsets[v + 1];
  }
  for (std::size_t v = 0; v < vertex_count; ++v) offsets[v + 1] += offsets[v];
  std::vector<std::uint32_t> corners(offsets.back());
  {
    std::vector<std::uint32_t> fill(offsets.begin(), offsets.end() - 1);
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      for (std::uint32_t k = 0; k < 3; ++k) {
        corners[fill[triangles[i][k]]++] = static_cast<std::uint32_t>(i * 3 + k);
      }
    }
  }

  std::vector<std::pair<std::uint32_t, std::uint32_t>> spokes;  // (other vertex, local corner)
  std::vector<std::uint32_t> parent;
  std::vector<std::uint32_t> fan_vertex;
  for (std::size_t v = 0; v < vertex_count; ++v) {
    const std::uint32_t begin = offsets[v];
    const std::uint32_t count = offsets[v + 1] - begin;
    if (count < 2) continue;
    spokes.clear();
    for (std::uint32_t c = 0; c < count; ++c) {
      const std::uint32_t corner = corners[begin + c];
      const Triangle& t = triangles[corner / 3];
      const std::uint32_t k = corner % 3;
      spokes.emplace_back(t[(k + 1) % 3], c);
      spokes.emplace_back(t[(k + 2) % 3], c);
    }
    std::sort(spokes.begin(), spokes.end());
    parent.resize(count);
    std::iota(parent.begin(), parent.end(), 0u);
    for (std::size_t i = 1; i < spokes.size(); ++i) {
      if (spokes[i].first != spokes[i - 1].first) continue;
      const std::uint32_t a = find_root(parent, spokes[i].second);
      const std::uint32_t b = find_root(parent, spokes[i - 1].second);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
    // The fan of local corner 0 keeps v; every other fan gets a copy.
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    fan_vertex.assign(count, kNone);
    for (std::uint32_t c = 0; c < count; ++c) {
      const std::uint32_t root = find_root(parent, c);
      if (fan_vertex[root] == kNone) {
        if (root == find_root(parent, 0u)) {
          fan_vertex[root] = static_cast<std::uint32_t>(v);
        } else {
          fan_vertex[root] = static_cast<std::uint32_t>(vertex_count + copies.size());
          copies.push_back(static_cast<std::uint32_t>(v));
        }
      }
      const std::uint32_t corner = corners[begin + c];
      triangles[corner / 3][corner % 3] = fan_vertex[root];
    }
  }
}

// Silences OpenMesh's error stream while it lives (add_face reports refusals there).
class QuietOpenMeshErrors {
 public:
  QuietOpenMeshErrors() : was_enabled_(::omerr().is_enabled()) {
    ::omerr().disable();
  }
  ~QuietOpenMeshErrors() {
    if (was_enabled_) ::omerr().enable();
  }
  QuietOpenMeshErrors(const QuietOpenMeshErrors&) = delete;
  QuietOpenMeshErrors& operator=(const QuietOpenMeshErrors&) = delete;

 private:
  bool was_enabled_;
};

}  // namespace

ToOpenMesh to_openmesh(const core::TriangleMesh& mesh) {
  ToOpenMesh result;
  const std::size_t n = mesh.positions.size();
  std::vector<Triangle> triangles = accept_manifold_edges(mesh, result);
  std::vector<std::uint32_t> copies;
  split_fans(triangles, n, copies);
  result.split_vertices = copies.size();

  OpenMeshTriMesh& om = result.mesh;
  om.reserve(n + copies.size(), triangles.size() * 3 / 2, triangles.size());
  std::vector<OpenMeshTriMesh::VertexHandle> handles;
  handles.reserve(n + copies.size());
  auto add_vertex = [&](std::size_t source) {
    const auto& p = mesh.positions[source];
    handles.push_back(om.add_vertex(OpenMeshTriMesh::Point(p[0], p[1], p[2])));
  };
  for (std::size_t v = 0; v < n; ++v) add_vertex(v);
  for (const std::uint32_t source : copies) add_vertex(source);

  const QuietOpenMeshErrors quiet;
  for (const Triangle& t : triangles) {
    const auto face = om.add_face(handles[t[0]], handles[t[1]], handles[t[2]]);
    if (!face.is_valid()) ++result.rejected_faces;
  }
  return result;
}

core::TriangleMesh from_openmesh(const OpenMeshTriMesh& mesh) {
  core::TriangleMesh result;
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> index(mesh.n_vertices(), kNone);
  const bool has_status = mesh.has_vertex_status();
  result.positions.reserve(mesh.n_vertices());
  for (const auto vh : mesh.all_vertices()) {
    if (has_status && mesh.status(vh).deleted()) continue;
    const auto& p = mesh.point(vh);
    index[static_cast<std::size_t>(vh.idx())] = static_cast<std::uint32_t>(result.positions.size());
    result.positions.push_back(
        {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
  }
  const bool has_face_status = mesh.has_face_status();
  result.triangles.reserve(mesh.n_faces());
  for (const auto fh : mesh.all_faces()) {
    if (has_face_status && mesh.status(fh).deleted()) continue;
    Triangle t{};
    int k = 0;
    for (const auto vh : mesh.fv_range(fh)) {
      assert(k < 3);
      t[k++] = index[static_cast<std::size_t>(vh.idx())];
    }
    assert(k == 3 && t[0] != kNone && t[1] != kNone && t[2] != kNone);
    result.triangles.push_back(t);
  }
  compute_vertex_normals(result);
  return result;
}

}  // namespace typemerge::mesh::detail
