// The disks step 1 of type merging finds (type_merging.h), in flat arrays that steps 2 and 3
// read: each disk's box, plane, loop, marching-cubes triangles and vertices, and the parts a
// composed disk falls back to.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/huge_pages.h"
#include "core/merge/geometry.h"

namespace typemerge::core::merge {

// A disk that passed every test (a block holds one or several), its loop in
// DiskStore::loops[loop_first, + loop_size), its marching-cubes triangles in
// DiskStore::triangles[triangles_first, + face_count) (their area vectors beside them in
// DiskStore::areas) and its vertices in DiskStore::vertices[vertices_first, + vertex_count).
struct MergedDisk {
  Box box;
  P3 normal;
  P3 area{0, 0, 0};   // the sum of its triangles' area vectors
  double band = 0.0;  // what the slab it lies in spans, in the tolerance's units (tolerance.h)
  std::uint32_t loop_first = 0;
  std::uint32_t loop_size = 0;
  std::uint32_t triangles_first = 0;
  std::uint32_t face_count = 0;
  std::uint32_t vertices_first = 0;
  std::uint32_t vertex_count = 0;
  std::int32_t size = 0;  // its block's edge in cubes
  // Its triangles (step 3) once triangulated; demoted = it could not be (or not with at most
  // as many triangles, caps and needles as marching cubes), so it keeps its own.
  std::uint32_t made_first = 0;
  std::uint32_t made_count = 0;
  bool demoted = false;
  // The disks it was composed of, kept in DiskStore::parts (their triangles among its own):
  // a disk whose triangulation is refused falls back to them (split) before marching cubes'
  // triangles.
  std::uint32_t parts_first = 0;
  std::uint32_t parts_count = 0;
  bool split = false;
};

// What a part of a composed disk keeps for its fallback (its loop and normal are found again
// from its triangles if it is needed: this is kept for every part, and splits are rare).
struct RetiredPart {
  Box box;
  std::uint32_t triangles_offset = 0;  // its triangles' start within its disk's
  std::uint32_t face_count = 0;
  std::uint32_t parts_first = 0;
  std::uint32_t parts_count = 0;
  std::int32_t size = 0;
};

struct DiskStore {
  // On huge pages: a fresh store faults its pages in as it is written (huge_pages.h).
  detail::HugePageVector<MergedDisk> disks;
  detail::HugePageVector<VertexId> loops;  // each disk's loop, counter-clockwise about its normal
  detail::HugePageVector<std::uint32_t> triangles;     // the disks' marching-cubes triangles (ids)
  detail::HugePageVector<std::array<float, 3>> areas;  // their area vectors
  detail::HugePageVector<VertexId> vertices;           // the disks' marching-cubes vertices
  std::vector<RetiredPart> parts;

  // Empties every array, keeping its capacity, and reserves room for a piece of
  // `piece_triangles` marching-cubes triangles and `piece_vertices` vertices: on CT surfaces
  // every triangle is in a disk, each vertex in about 2.6 disks' vertices and 2.4 loops, and
  // there is about a disk for every five triangles (room is kept for one every four). Only
  // the pages written are mapped; a store that outgrows this grows as a vector does.
  void reset(std::size_t piece_triangles, std::size_t piece_vertices) {
    disks.clear();
    loops.clear();
    triangles.clear();
    areas.clear();
    vertices.clear();
    parts.clear();
    disks.reserve(piece_triangles / 4);
    loops.reserve(3 * piece_vertices);
    triangles.reserve(piece_triangles);
    areas.reserve(piece_triangles);
    vertices.reserve(3 * piece_vertices);
  }

  std::span<const VertexId> loop_of(const MergedDisk& disk) const {
    return std::span(loops).subspan(disk.loop_first, disk.loop_size);
  }
};

}  // namespace typemerge::core::merge
