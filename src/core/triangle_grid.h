// TriangleGrid: the triangles of a fixed mesh bucketed in a uniform grid, for nearest-surface
// queries (mesh_distance.h, bounded_collapse.h).
//
// Cells about two mean edge lengths wide (about two triangles a cell on a surface), at most
// 1,024 along an axis so a stray far triangle cannot blow the grid up, and at most four cells
// a triangle over the bounding box; CSR storage, 4 bytes a bucket entry and 4 a cell, and each
// triangle's bounding box in floats (24 bytes a triangle). A query searches shells of cells
// outward and stops once no unvisited cell can be nearer than the best triangle found (or than
// a cap).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/mesh.h"
#include "core/mesh_distance.h"

namespace typemerge::core::detail {

using Point3 = std::array<double, 3>;
inline Point3 as_point3(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

inline constexpr double kCellsPerTriangle = 4.0;

// Triangles of a mesh bucketed by the grid cells their bounding boxes overlap (CSR). The mesh
// must outlive the grid and not change; it must have at least one triangle.
class TriangleGrid {
 public:
  explicit TriangleGrid(const TriangleMesh& mesh) : mesh_(mesh) {
    // Each triangle's box first; the mesh's box and the buckets are read from them.
    boxes_.resize(mesh.triangles.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& a = mesh.positions[mesh.triangles[t][0]];
      const auto& b = mesh.positions[mesh.triangles[t][1]];
      const auto& c = mesh.positions[mesh.triangles[t][2]];
      for (int k = 0; k < 3; ++k) {
        boxes_[t][k] = std::min({a[k], b[k], c[k]});
        boxes_[t][k + 3] = std::max({a[k], b[k], c[k]});
      }
    }
    lo_ = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
           std::numeric_limits<double>::max()};
    Point3 hi = {-lo_[0], -lo_[1], -lo_[2]};
    for (const std::array<float, 6>& box : boxes_) {
      for (int a = 0; a < 3; ++a) {
        lo_[a] = std::min(lo_[a], double{box[a]});
        hi[a] = std::max(hi[a], double{box[a + 3]});
      }
    }
    // Cell edge: about two triangles per cell for a surface (cells ~ area / edge²).
    for (const auto& t : mesh.triangles) {
      const Point3 p0 = as_point3(mesh.positions[t[0]]);
      const Point3 p1 = as_point3(mesh.positions[t[1]]);
      mean_edge_ += std::sqrt((p1[0] - p0[0]) * (p1[0] - p0[0]) +
                              (p1[1] - p0[1]) * (p1[1] - p0[1]) + (p1[2] - p0[2]) * (p1[2] - p0[2]));
    }
    mean_edge_ /= static_cast<double>(mesh.triangles.size());
    cell_ = std::max(2.0 * mean_edge_, 1e-9);
    for (int a = 0; a < 3; ++a) {
      // Cap the cell count per axis so a stray far triangle cannot blow up the grid.
      const double extent = hi[a] - lo_[a];
      cell_ = std::max(cell_, extent / 1024.0);
    }
    // And at most kCellsPerTriangle cells a triangle over the bounding box: a surface fills
    // few of its box's cells, and the dense cell table (4 bytes a cell) would otherwise
    // outweigh the mesh (36 M cells, 146 MB, for the abdomen's 2.2 M-triangle skin).
    const double most_cells =
        std::max(kCellsPerTriangle * static_cast<double>(mesh.triangles.size()), 64.0);
    auto cells_at = [&](double c) {
      double n = 1.0;
      for (int a = 0; a < 3; ++a) n *= std::floor((hi[a] - lo_[a]) / c) + 1.0;
      return n;
    };
    while (cells_at(cell_) > most_cells) cell_ *= 1.25;
    for (int a = 0; a < 3; ++a) dims_[a] = static_cast<int>((hi[a] - lo_[a]) / cell_) + 1;
    const std::size_t cells = static_cast<std::size_t>(dims_[0]) * dims_[1] * dims_[2];
    start_.assign(cells + 1, 0);
    // Count, prefix sum, fill; the fill advances start_[c + 1] from the beginning of cell c to
    // its end, i.e. to the beginning of cell c + 1, so no second table is needed.
    for_each_cell_of_triangles([&](std::size_t cell, std::uint32_t) { ++start_[cell + 1]; });
    for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
    entries_.resize(start_[cells]);
    for (std::size_t c = cells; c > 0; --c) start_[c] = start_[c - 1];  // start_[c + 1]: c's start
    for_each_cell_of_triangles(
        [&](std::size_t cell, std::uint32_t t) { entries_[start_[cell + 1]++] = t; });
  }

  // Squared distance from p to the nearest triangle; `stamp` (one entry per triangle, owned by
  // the calling thread) avoids testing a triangle twice per query.
  // With `cap` finite, the search stops once no triangle nearer than cap is left, returning
  // at most cap². With `which`, the nearest triangle's index is stored there (unchanged when
  // none is nearer than cap). With `enough` > 0, the search stops at the first triangle whose
  // squared distance is below it (then the result is that, not necessarily the nearest).
  double nearest_squared(const Point3& p, std::vector<std::uint32_t>& stamp, std::uint32_t query,
                         double cap = std::numeric_limits<double>::infinity(),
                         std::uint32_t* which = nullptr, double enough = 0.0) const {
    return search(p, stamp, query, cap * cap, which, enough);
  }

  // nearest_squared (with `cap`), seeded with triangle `hint` (a triangle index, or any larger
  // value for none): its distance bounds the search before the first cell, so a query near the
  // previous one, given that one's nearest triangle, visits few cells. The result is the same
  // as without the seed; `hint` becomes the nearest triangle (unchanged when none is nearer
  // than cap).
  double nearest_squared_from(const Point3& p, std::vector<std::uint32_t>& stamp,
                              std::uint32_t query, double cap, std::uint32_t& hint) const {
    double best = cap * cap;
    if (hint < mesh_.triangles.size()) {
      stamp[hint] = query;
      const auto& tri = mesh_.triangles[hint];
      best = std::min(best, point_triangle_distance_squared(p, as_point3(mesh_.positions[tri[0]]),
                                                             as_point3(mesh_.positions[tri[1]]),
                                                             as_point3(mesh_.positions[tri[2]])));
    }
    return search(p, stamp, query, best, &hint, 0.0);
  }

  // The mean length of the triangles' first edges.
  double mean_edge() const { return mean_edge_; }

  // Calls f(t) once for every triangle bucketed in a cell that meets the box [lo, hi]: every
  // triangle that meets the box, and some near it (`stamp` and `query` as for the searches).
  template <typename F>
  void visit_box(const Point3& lo, const Point3& hi, std::vector<std::uint32_t>& stamp,
                 std::uint32_t query, const F& f) const {
    std::array<int, 3> c0{};
    std::array<int, 3> c1{};
    for (int a = 0; a < 3; ++a) {
      if (hi[a] < lo_[a] || lo[a] > lo_[a] + dims_[a] * cell_) return;
      const double last = dims_[a] - 1.0;  // clamped before the cast: a far box cannot overflow
      c0[a] = static_cast<int>(std::clamp(std::floor((lo[a] - lo_[a]) / cell_), 0.0, last));
      c1[a] = static_cast<int>(std::clamp(std::floor((hi[a] - lo_[a]) / cell_), 0.0, last));
    }
    for (int z = c0[2]; z <= c1[2]; ++z) {
      for (int y = c0[1]; y <= c1[1]; ++y) {
        for (int x = c0[0]; x <= c1[0]; ++x) {
          const std::size_t cell = cell_index(x, y, z);
          for (std::uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
            const std::uint32_t t = entries_[i];
            if (stamp[t] == query) continue;
            stamp[t] = query;
            f(t);
          }
        }
      }
    }
  }

 private:
  // The shell search from the cell of p, with `best` the squared distance to beat.
  double search(const Point3& p, std::vector<std::uint32_t>& stamp, std::uint32_t query,
                double best, std::uint32_t* which, double enough) const {
    std::array<int, 3> c{};
    for (int a = 0; a < 3; ++a) {
      c[a] = std::clamp(static_cast<int>(std::floor((p[a] - lo_[a]) / cell_)), 0, dims_[a] - 1);
    }
    const int max_ring = std::max({dims_[0], dims_[1], dims_[2]});
    for (int r = 0; r <= max_ring; ++r) {
      // The shell of cells at Chebyshev distance r from c, clipped to the grid.
      const int z0 = std::max(c[2] - r, 0), z1 = std::min(c[2] + r, dims_[2] - 1);
      const int y0 = std::max(c[1] - r, 0), y1 = std::min(c[1] + r, dims_[1] - 1);
      const int x0 = std::max(c[0] - r, 0), x1 = std::min(c[0] + r, dims_[0] - 1);
      for (int z = z0; z <= z1; ++z) {
        for (int y = y0; y <= y1; ++y) {
          const bool inner = std::abs(z - c[2]) < r && std::abs(y - c[1]) < r;
          auto cell = [&](int x) {
            visit(x, y, z, p, stamp, query, best, which);
            return best < enough;
          };
          if (!inner) {
            for (int x = x0; x <= x1; ++x) {
              if (cell(x)) return best;
            }
          } else {
            if (c[0] - r >= 0 && cell(c[0] - r)) return best;
            if (r > 0 && c[0] + r < dims_[0] && cell(c[0] + r)) return best;
          }
        }
      }
      // Every cell outside the block [c − r, c + r] is at least `gap` away from p; once the
      // block holds the whole grid there is none.
      if (z0 == 0 && y0 == 0 && x0 == 0 && z1 == dims_[2] - 1 && y1 == dims_[1] - 1 &&
          x1 == dims_[0] - 1) {
        break;
      }
      double gap = std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        gap = std::min(gap, p[a] - (lo_[a] + (c[a] - r) * cell_));
        gap = std::min(gap, lo_[a] + (c[a] + r + 1) * cell_ - p[a]);
      }
      if (gap > 0.0 && gap * gap >= best) break;
    }
    return best;
  }

  template <typename F>
  void for_each_cell_of_triangles(const F& f) const {
    for (std::uint32_t t = 0; t < mesh_.triangles.size(); ++t) {
      std::array<int, 3> c0{};
      std::array<int, 3> c1{};
      for (int a = 0; a < 3; ++a) {
        const double mn = boxes_[t][a];
        const double mx = boxes_[t][a + 3];
        c0[a] = std::clamp(static_cast<int>((mn - lo_[a]) / cell_), 0, dims_[a] - 1);
        c1[a] = std::clamp(static_cast<int>((mx - lo_[a]) / cell_), 0, dims_[a] - 1);
      }
      for (int z = c0[2]; z <= c1[2]; ++z) {
        for (int y = c0[1]; y <= c1[1]; ++y) {
          for (int x = c0[0]; x <= c1[0]; ++x) f(cell_index(x, y, z), t);
        }
      }
    }
  }

  std::size_t cell_index(int x, int y, int z) const {
    return static_cast<std::size_t>(x) +
           static_cast<std::size_t>(dims_[0]) *
               (static_cast<std::size_t>(y) + static_cast<std::size_t>(dims_[1]) * z);
  }

  // Squared distance from p to the box [lo, hi] (0 inside).
  static double box_distance_squared(const Point3& p, const Point3& lo, const Point3& hi) {
    double d2 = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double d = std::max({lo[a] - p[a], 0.0, p[a] - hi[a]});
      d2 += d * d;
    }
    return d2;
  }

  void visit(int x, int y, int z, const Point3& p, std::vector<std::uint32_t>& stamp,
             std::uint32_t query, double& best, std::uint32_t* which) const {
    const Point3 cell_lo = {lo_[0] + x * cell_, lo_[1] + y * cell_, lo_[2] + z * cell_};
    const Point3 cell_hi = {cell_lo[0] + cell_, cell_lo[1] + cell_, cell_lo[2] + cell_};
    // A triangle's nearest point to p lies in some cell the triangle is bucketed in; that cell
    // is nearer than `best` whenever the triangle matters, so farther cells can be skipped
    // (without stamping their triangles).
    if (box_distance_squared(p, cell_lo, cell_hi) >= best) return;
    const std::size_t cell = cell_index(x, y, z);
    for (std::uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
      const std::uint32_t t = entries_[i];
      if (stamp[t] == query) continue;
      stamp[t] = query;
      const std::array<float, 6>& box = boxes_[t];
      if (box_distance_squared(p, {box[0], box[1], box[2]}, {box[3], box[4], box[5]}) >= best) {
        continue;
      }
      const auto& tri = mesh_.triangles[t];
      const double d2 = point_triangle_distance_squared(p, as_point3(mesh_.positions[tri[0]]),
                                                        as_point3(mesh_.positions[tri[1]]),
                                                        as_point3(mesh_.positions[tri[2]]));
      if (d2 < best) {
        best = d2;
        if (which != nullptr) *which = t;
      }
    }
  }

  const TriangleMesh& mesh_;
  double mean_edge_ = 0.0;
  Point3 lo_{};
  double cell_ = 1.0;
  std::array<int, 3> dims_{};
  std::vector<std::uint32_t> start_;
  std::vector<std::uint32_t> entries_;
  // Per triangle, its bounding box (lo, hi; floats, as the positions): a query's box test
  // reads one record instead of three positions.
  std::vector<std::array<float, 6>> boxes_;
};

}  // namespace typemerge::core::detail
