// Step 3 of type merging (type_merging.h): every merged disk's loop (less its thinned
// vertices) triangulated by LoopTriangulator, with the fallback chain that keeps every disk
// no worse than marching cubes there.
//
// A disk is accepted when its loop of n vertices makes n − 2 ≤ its marching-cubes triangles,
// the triangulation succeeds (for a thinned loop: its projection is still simple) and it has
// no more caps (an angle above 170°) and no more needles (below 1°), in millimetres, than its
// marching-cubes triangles. A disk refused gets its thinned vertices back (and the one other
// disk through each such vertex is triangulated again, as its loop changed); refused with its
// whole loop, it falls back to the disks it was composed of (their loops rebuilt from their
// triangles, each then triangulated the same way), or, made of none, keeps its marching-cubes
// triangles. This ends: vertices only come back and disks only split.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/merge/blocks.h"
#include "core/merge/disk_store.h"
#include "core/merge/local_table.h"
#include "core/merge/loop_thinning.h"
#include "core/merge/loop_triangulation.h"
#include "core/type_merging.h"
#include "core/volume.h"

namespace typemerge::core::merge {

// Triangulates the store's disks as above and appends every disk's final triangles (new, or
// marching cubes' for a demoted one) to `out`, in disk order. Reads and writes `state`
// (vertices given back become kKept), may append parts to the store; counts the merged disks
// by size, the demoted and split ones, the vertices restored and the passes in `stats`.
// `axes`: one index step in mm (IndexToPatient::axes), where shapes are judged. `made`:
// scratch for the disks' new triangles (emptied first, its capacity kept for the next piece).
void triangulate_disks(const PieceSurface& piece, const std::array<Vec3, 3>& axes,
                       const LoopOwners& owners, DiskStore& store,
                       std::vector<std::uint8_t>& state, LocalTable& table,
                       LoopTriangulator& triangulator, std::vector<Triangle>& made,
                       std::vector<Triangle>& out, MergeStats& stats);

}  // namespace typemerge::core::merge
