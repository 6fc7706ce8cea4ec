#include "core/merge/piece_merge.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <utility>

#include "core/huge_pages.h"
#include "core/merge/blocks.h"
#include "core/merge/disk_store.h"
#include "core/merge/disk_test.h"
#include "core/merge/disk_triangulation.h"
#include "core/merge/local_table.h"
#include "core/merge/loop_thinning.h"
#include "core/merge/loop_triangulation.h"
#include "core/merge/tolerance.h"

namespace typemerge::core::merge {
namespace {

// The three steps on one piece's marching-cubes surface; returns its triangles.
std::vector<Triangle> merge_surface(const PieceSurface& piece, const Box& lattice,
                                    const IndexToPatient& geometry, const MergeOptions& options,
                                    DiskStore& store, MergeStats& stats) {
  const std::span<const Position> positions = piece.mesh.positions;
  const std::array<double, 3> spacing =
      options.blocks_follow_spacing
          ? std::array<double, 3>{geometry.spacing(0), geometry.spacing(1), geometry.spacing(2)}
          : std::array<double, 3>{1.0, 1.0, 1.0};
  LocalTable table(positions);
  LoopTriangulator triangulator(geometry.axes);
  store.reset(piece.mesh.triangles.size(), positions.size());
  std::vector<Triangle> out;
  detail::reserve_on_huge_pages(out, piece.mesh.triangles.size() / 2);

  const Tolerance tolerance = options.epsilon_mm > 0.0
                                  ? Tolerance::in_mm(options.epsilon_mm, geometry.axes)
                                  : Tolerance::in_voxels(options.epsilon_voxels);
  DiskTest test(positions, piece.mesh.triangles, tolerance, table, triangulator);
  test_blocks(piece, lattice, block_dims(geometry, options), spacing, test, store, out, stats);

  std::vector<std::uint8_t> state(positions.size(), kOpen);
  const LoopOwners owners(positions, store);
  thin_shared_faces(positions, store, owners, tolerance, state, stats);

  triangulate_disks(piece, geometry.axes, owners, store, state, table, triangulator, out, stats);
  return out;
}

}  // namespace

MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const MergeOptions& options, std::int64_t first, std::int64_t last,
                        PieceScratch& scratch, double expected_vertices) {
  const bool normals = extract.vertex_normals;
  detail::SurfacePiece piece =
      detail::extract_layers(volume, iso, extract, first, last, /*defer_normals=*/normals,
                             expected_vertices, &scratch.surface);
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
  std::vector<Triangle> triangles =
      merge_surface({piece.mesh, piece.cubes}, lattice, volume.geometry(), options,
                    scratch.store, out.stats);

  // Compaction: the vertices still used, in their order (so the seam's stay first, in order).
  std::vector<VertexId> new_id(piece.mesh.positions.size(), kNone);
  for (const Triangle& t : triangles) {
    for (VertexId v : t) new_id[v] = 0;
  }
  const auto kept = static_cast<std::size_t>(std::count(new_id.begin(), new_id.end(), 0));
  detail::reserve_on_huge_pages(out.mesh.positions, kept);
  if (normals) detail::reserve_on_huge_pages(out.mesh.normals, kept);
  VertexId next = 0;
  for (VertexId v = 0; v < new_id.size(); ++v) {
    if (new_id[v] == 0) {
      new_id[v] = next;
      out.mesh.positions.push_back(piece.mesh.positions[v]);
      if (normals) {
        out.mesh.normals.push_back(detail::deferred_vertex_normal(
            volume, iso, extract.close_borders, piece.vertex_edges[v], piece.centroid_normals));
      }
      ++next;
    }
  }
  for (Triangle& t : triangles) {
    for (VertexId& v : t) v = new_id[v];
  }
  out.mesh.triangles = std::move(triangles);
  // Seam vertices lie on block faces, so they are loop vertices and stay.
  for (std::size_t v = 0; v < out.shared; ++v) {
    if (new_id[v] != v) throw std::logic_error("type merging dropped a seam vertex");
  }
  for (std::size_t v = piece.top_first; v < piece.top_end; ++v) {
    if (new_id[v] == kNone) throw std::logic_error("type merging dropped a seam vertex");
    out.top.push_back(new_id[v]);
  }
  out.stats.triangles_after = out.mesh.triangles.size();
  out.stats.vertices_after = out.mesh.positions.size() - out.shared;
  scratch.surface = std::move(piece);
  return out;
}

void append_piece(TriangleMesh& out, const MergedPiece& piece, std::vector<VertexId>& seam) {
  if (piece.shared != seam.size()) {
    throw std::logic_error("type merging: pieces disagree about their seam");
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
  if (!piece.mesh.normals.empty()) {
    out.normals.insert(out.normals.end(), piece.mesh.normals.begin() + own,
                       piece.mesh.normals.end());
  }
  for (const auto& t : piece.mesh.triangles) {
    out.triangles.push_back({output_id(t[0]), output_id(t[1]), output_id(t[2])});
  }
  std::vector<VertexId> top;
  top.reserve(piece.top.size());
  for (VertexId v : piece.top) top.push_back(output_id(v));
  seam = std::move(top);
}

}  // namespace typemerge::core::merge
