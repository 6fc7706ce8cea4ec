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

// Step 1 as marching cubes makes the piece: each layer of blocks is tested as soon as its
// last cube layer is triangulated, while that layer's triangles and vertices are still in the
// processor's cache (tested after the whole piece, they were read back from memory). Then
// steps 2 and 3 on the piece made (finish).
class MergeAsExtracted final : public detail::LayerObserver {
 public:
  // reads_below: told, after each cube layer, the slices below which marching cubes reads
  // no more (none when null).
  MergeAsExtracted(const Box& lattice, std::int64_t pad, const IndexToPatient& geometry,
                   const MergeOptions& options, PieceScratch& scratch, MergeStats& stats,
                   const std::function<void(std::int64_t below)>* reads_below)
      : lattice_(lattice),
        pad_(pad),
        geometry_(geometry),
        block_(block_dims(geometry, options)),
        spacing_(options.blocks_follow_spacing
                     ? std::array<double, 3>{geometry.spacing(0), geometry.spacing(1),
                                             geometry.spacing(2)}
                     : std::array<double, 3>{1.0, 1.0, 1.0}),
        tolerance_(options.epsilon_mm > 0.0
                       ? Tolerance::in_mm(options.epsilon_mm, geometry.axes)
                       : Tolerance::in_voxels(options.epsilon_voxels)),
        triangulator_(geometry.axes),
        scratch_(scratch),
        stats_(stats),
        reads_below_(reads_below) {}

  void layer_done(std::int64_t layer, const TriangleMesh& mesh,
                  std::span<const BoundaryCube> cubes) override {
    const auto z = static_cast<std::int32_t>(layer - pad_);
    // Cube layer `layer` joined slices layer and layer + 1 (padded numbering); the next reads
    // from layer + 1 up, i.e. the volume's slice layer + 1 − pad.
    if (reads_below_ != nullptr) (*reads_below_)(layer + 1 - pad_);
    if ((z - lattice_.lo[2] + 1) % block_[2] == 0 || z + 1 == lattice_.hi[2]) {
      test_new_blocks(mesh, cubes);
    }
  }

  // Steps 2 and 3 on the piece's surface as marching cubes left it; the merged triangles
  // into scratch.triangles.
  void finish(const PieceSurface& piece) {
    // The last cube layer ends a layer of blocks: every cube's blocks were tested.
    if (!started_ || tested_cubes_ != piece.cubes.size()) {
      throw std::logic_error("type merging: a piece's blocks were not all tested");
    }
    const std::size_t vertex_room = piece.mesh.positions.capacity();
    const std::span<const Position> positions = piece.mesh.positions;
    std::vector<std::uint8_t>& state = scratch_.state;
    state.reserve(vertex_room);
    state.assign(positions.size(), kOpen);
    scratch_.owners.disks.reserve(vertex_room);
    scratch_.owners.count.reserve(vertex_room);
    scratch_.owners.inside_face.reserve(vertex_room);
    const LoopOwners owners(positions, scratch_.store, scratch_.owners);
    thin_shared_faces(positions, scratch_.store, owners, tolerance_, state, stats_);

    scratch_.made.reserve(piece.mesh.triangles.capacity() / 2);
    scratch_.table.extend(positions);
    triangulate_disks(piece, geometry_.axes, owners, scratch_.store, state, scratch_.table,
                      triangulator_, scratch_.made, scratch_.triangles, stats_);
    if (!scratch_.keep) scratch_.release_merge_arrays();
  }

 private:
  // Step 1 on the blocks of the cubes made since the last call.
  void test_new_blocks(const TriangleMesh& mesh, std::span<const BoundaryCube> cubes) {
    if (!started_) {
      // Room in the scratch's arrays for the largest piece (marching cubes' outputs were
      // reserved for it), so that a later, larger piece does not move them to fresh pages.
      const std::size_t vertex_room = mesh.positions.capacity();
      const std::size_t triangle_room = mesh.triangles.capacity();
      scratch_.table.reset(mesh.positions, vertex_room);
      scratch_.store.reset(triangle_room, vertex_room);
      scratch_.triangles.clear();
      scratch_.triangles.reserve(triangle_room / 2);
      started_ = true;
    }
    if (tested_cubes_ == cubes.size()) return;
    scratch_.table.extend(mesh.positions);
    DiskTest test(mesh.positions, mesh.triangles, tolerance_, scratch_.table, triangulator_);
    test_blocks({mesh, cubes}, lattice_, block_, spacing_, test, scratch_.store,
                scratch_.triangles, stats_, tested_cubes_);
    tested_cubes_ = cubes.size();
  }

  Box lattice_;
  std::int64_t pad_;
  const IndexToPatient& geometry_;
  Dims block_;
  std::array<double, 3> spacing_;
  Tolerance tolerance_;
  LoopTriangulator triangulator_;
  PieceScratch& scratch_;
  MergeStats& stats_;
  const std::function<void(std::int64_t below)>* reads_below_;
  bool started_ = false;
  std::size_t tested_cubes_ = 0;
};

}  // namespace

void PieceScratch::release_merge_arrays() {
  table = LocalTable();
  owners = LoopOwners::Arrays();
  state = {};
  made = {};
}

MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const MergeOptions& options, std::int64_t first, std::int64_t last,
                        PieceScratch& scratch, double expected_vertices,
                        const std::function<void(std::int64_t below)>& reads_below) {
  const bool normals = extract.vertex_normals;
  const std::int32_t pad = extract.close_borders ? 1 : 0;
  const VolumeSize& size = volume.size();
  Box lattice;
  lattice.lo = {-pad, -pad, static_cast<std::int32_t>(first) - pad};
  lattice.hi = {static_cast<std::int32_t>(size.nx - 1 + pad),
                static_cast<std::int32_t>(size.ny - 1 + pad),
                static_cast<std::int32_t>(last) - pad};
  MergedPiece out;
  MergeAsExtracted merge(lattice, pad, volume.geometry(), options, scratch, out.stats,
                         reads_below && !normals ? &reads_below : nullptr);
  detail::SurfacePiece piece =
      detail::extract_layers(volume, iso, extract, first, last, /*defer_normals=*/normals,
                             expected_vertices, &scratch.surface, &merge);
  // The slice buffers (two slices' edge tables) are idle while the piece merges: freed after
  // the thread's last piece; with return_idle_pages, else their pages returned until the
  // thread's next piece's marching cubes.
  if (!scratch.keep) {
    piece.slice_buffers.reset();
  } else if (options.return_idle_pages && piece.slice_buffers) {
    piece.slice_buffers->release_pages();
  }
  if (reads_below && !normals) reads_below(size.nz);
  out.shared = piece.shared_vertices;
  out.ambiguity = piece.stats;
  out.stats.triangles_before = piece.mesh.triangles.size();
  out.stats.vertices_before = piece.mesh.positions.size() - piece.shared_vertices;
  merge.finish({piece.mesh, piece.cubes});
  const std::vector<Triangle>& triangles = scratch.triangles;

  // Compaction: the vertices still used, in their order (so the seam's stay first, in order),
  // into the scratch's output arrays.
  out.mesh = std::move(scratch.output);
  out.mesh.positions.clear();
  out.mesh.normals.clear();
  out.mesh.triangles.clear();
  std::vector<VertexId>& new_id = scratch.new_id;
  new_id.reserve(piece.mesh.positions.capacity());
  new_id.assign(piece.mesh.positions.size(), kNone);
  for (const Triangle& t : triangles) {
    for (VertexId v : t) new_id[v] = 0;
  }
  const auto kept = static_cast<std::size_t>(std::count(new_id.begin(), new_id.end(), 0));
  // Arrays that are too small get a quarter more room than needed, so that they serve a
  // somewhat larger piece after this one; huge pages only where this piece writes (a 2 MiB
  // page in the room beyond would be mapped whole for its first bytes).
  const auto make_room = [](auto& v, std::size_t n) {
    if (v.capacity() < n) v.reserve(n + n / 4);
    detail::advise_huge_pages(v.data(), n * sizeof(v[0]));
  };
  make_room(out.mesh.positions, kept);
  if (normals) make_room(out.mesh.normals, kept);
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
  make_room(out.mesh.triangles, triangles.size());
  for (const Triangle& t : triangles) {
    out.mesh.triangles.push_back({new_id[t[0]], new_id[t[1]], new_id[t[2]]});
  }
  // Seam vertices lie on block faces, so they are loop vertices and stay.
  for (std::size_t v = 0; v < out.shared; ++v) {
    if (new_id[v] != v) throw std::logic_error("type merging dropped a seam vertex");
  }
  for (std::size_t v = piece.top_first; v < piece.top_end; ++v) {
    if (new_id[v] == kNone) throw std::logic_error("type merging dropped a seam vertex");
    out.top.push_back(new_id[v]);
  }
  if (reads_below && normals) reads_below(volume.size().nz);
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
