#include "core/inner_wall.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "core/distance_transform.h"
#include "core/marching_cubes.h"
#include "core/mesh_distance.h"
#include "core/page_release.h"
#include "core/ray_parity.h"
#include "core/union_find.h"

namespace typemerge::core {
namespace {

using Point = std::array<double, 3>;

Point cross(const Point& a, const Point& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Point to_point(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

// Bounds of the stretch |A v| / |v| of the grid's unit axes A (1 and 1 for orthogonal axes):
// Gershgorin discs of the Gram matrix AᵀA, whose diagonal is 1.
std::array<double, 2> stretch_bounds(const IndexToPatient& geometry) {
  std::array<Point, 3> unit{};
  for (int a = 0; a < 3; ++a) {
    const double length = geometry.spacing(a);
    for (int c = 0; c < 3; ++c) unit[a][c] = geometry.axes[a][c] / length;
  }
  double radius = 0;
  for (int a = 0; a < 3; ++a) {
    double row = 0;
    for (int b = 0; b < 3; ++b) row += a == b ? 0.0 : std::abs(dot(unit[a], unit[b]));
    radius = std::max(radius, row);
  }
  return {std::sqrt(std::max(1.0 - radius, 1e-6)), std::sqrt(1.0 + radius)};
}

double signed_volume(const TriangleMesh& mesh, const std::vector<std::uint32_t>& triangles) {
  double volume = 0;
  for (std::uint32_t t : triangles) {
    const auto& tri = mesh.triangles[t];
    volume += dot(to_point(mesh.positions[tri[0]]),
                  cross(to_point(mesh.positions[tri[1]]), to_point(mesh.positions[tri[2]])));
  }
  return volume / 6.0;
}

// Outside samples (0) that no 6-connected path of outside samples joins to the volume's
// border become inside (infinity): the air pockets a cavity-filling finish removed.
void fill_enclosed_outside(std::span<float> d, const VolumeSize& size) {
  std::vector<std::uint8_t> reached(d.size(), 0);
  std::vector<std::size_t> stack;
  const std::int64_t nx = size.nx, ny = size.ny, nz = size.nz;
  auto push = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    const auto v = static_cast<std::size_t>(i + nx * (j + ny * k));
    if (d[v] == 0.0f && reached[v] == 0) {
      reached[v] = 1;
      stack.push_back(v);
    }
  };
  for (std::int64_t k = 0; k < nz; ++k) {
    for (std::int64_t j = 0; j < ny; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        if (i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1) push(i, j, k);
      }
    }
  }
  while (!stack.empty()) {
    const std::size_t v = stack.back();
    stack.pop_back();
    const auto i = static_cast<std::int64_t>(v) % nx;
    const auto j = (static_cast<std::int64_t>(v) / nx) % ny;
    const auto k = static_cast<std::int64_t>(v) / (nx * ny);
    if (i > 0) push(i - 1, j, k);
    if (i + 1 < nx) push(i + 1, j, k);
    if (j > 0) push(i, j - 1, k);
    if (j + 1 < ny) push(i, j + 1, k);
    if (k > 0) push(i, j, k - 1);
    if (k + 1 < nz) push(i, j, k + 1);
  }
  for (std::size_t v = 0; v < d.size(); ++v) {
    if (d[v] == 0.0f && reached[v] == 0) d[v] = std::numeric_limits<float>::infinity();
  }
}

}  // namespace


namespace {

// What step 3 needs besides the distances.
struct Band {
  double lo = 0, hi = 0;            // D range measured exactly
  double sigma_min = 1, diagonal = 0, deviation = 0;  // out of it, F = σ_min·D − r − m, >= 0
  double search = 0;                // point_to_mesh_distances' cap
  const IndexToPatient* geometry = nullptr;
  const TriangleMesh* outer = nullptr;
  unsigned threads = 0;
};

// F on slices [k0, k1) of a grid of size `size`, from their squared distances `d2` (slice k0
// first), written to `out` (slice k0 first; may be d2). Returns the band samples' count.
std::size_t field_slices(const float* d2, float* out, std::int64_t k0, std::int64_t k1,
                         const VolumeSize& size, const Band& band) {
  std::vector<std::uint32_t> band_index;        // sample index from slice k0
  std::vector<std::array<float, 3>> positions;  // band samples' centres, patient mm
  std::size_t v = 0;
  for (std::int64_t k = k0; k < k1; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 0; i < size.nx; ++i, ++v) {
        const double d = std::sqrt(static_cast<double>(d2[v]));
        // Outside samples (D = 0) stay 0 whatever the band: they are below the level.
        if (d > 0 && d >= band.lo && d <= band.hi) {
          band_index.push_back(static_cast<std::uint32_t>(v));
          const Vec3 p = band.geometry->apply(double(i), double(j), double(k));
          positions.push_back(
              {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
        } else {
          out[v] = static_cast<float>(
              std::max(0.0, band.sigma_min * d - band.diagonal - band.deviation));
        }
      }
    }
  }
  // Exact distances of the band samples to the outer surface. A sample farther than the
  // band's top from the outer surface is above the level whatever its exact distance: the
  // search stops there.
  const std::vector<float> exact =
      point_to_mesh_distances(positions, *band.outer, band.threads, band.search);
  for (std::size_t b = 0; b < band_index.size(); ++b) out[band_index[b]] = exact[b];
  return band_index.size();
}

// Steps 1–4 over the whole volume at once (a float field of every sample).
TriangleMesh whole_volume_wall(const Volume& field, float iso, const InnerWallOptions& options,
                               const Band& band, const ExtractOptions& extract, double level,
                               InnerWallStats& s) {
  const auto& size = field.size();
  const IndexToPatient& geometry = field.geometry();
  const std::array<double, 3> spacing = {geometry.spacing(0), geometry.spacing(1),
                                         geometry.spacing(2)};
  // 1–2. D², in the field's storage: seeds (0) at the outside samples.
  Volume distance(size, geometry);
  auto& d = distance.samples();
  constexpr float kFar = std::numeric_limits<float>::infinity();
  field.visit([&](const auto* values) {
    for (std::size_t v = 0; v < d.size(); ++v) d[v] = values[v] >= iso ? kFar : 0.0f;
  });
  if (options.fill_enclosed) fill_enclosed_outside(d, size);
  squared_distance_transform(d, size, spacing, /*seeds_beyond_border=*/true, options.threads);
  // 3. F, in place.
  s.band_samples = field_slices(d.data(), d.data(), 0, size.nz, size, band);
  // 4.
  return extract_isosurface(distance, static_cast<float>(level), extract);
}

// Steps 1–4 in slabs of cube layers: each slab's distances from a scratch of its slices and a
// halo (exact up to `reach` mm), F written into a field whose slices are touched only while a
// piece reads them (its pages are returned afterwards), the pieces stitched as
// extract_isosurface stitches its slabs. The same bytes as whole_volume_wall: every value a
// piece reads that can differ (a deeper sample's lower bound) is above the level and more
// than a cube and a gradient step from any crossing.
TriangleMesh slab_wall(const Volume& field, float iso, const InnerWallOptions& options,
                       const Band& band, const ExtractOptions& extract, double level,
                       double reach, InnerWallStats& s) {
  const auto& size = field.size();
  const IndexToPatient& geometry = field.geometry();
  const std::array<double, 3> spacing = {geometry.spacing(0), geometry.spacing(1),
                                         geometry.spacing(2)};
  // Every sample is written before a piece reads it; pages untouched cost no memory.
  Volume distance = Volume::uninitialized(size, geometry);
  const auto level_f = static_cast<float>(level);
  const std::int64_t layers = detail::cube_layer_count(distance, level_f, extract);
  TriangleMesh inner;
  if (layers == 0) return inner;
  const std::int64_t plane = size.nx * size.ny;
  const auto halo = static_cast<std::int64_t>(std::ceil(reach / spacing[2])) + 1;
  const std::int64_t step = std::max<std::int64_t>(1, options.slab_layers);
  std::vector<float> d2;
  std::int64_t computed = 0;  // F holds slices [released, computed)
  std::int64_t released = 0;
  std::size_t below = 0;      // the previous piece's top slice vertices, in `inner`
  detail::SurfacePiece piece;  // each piece is written into the previous one's arrays
  for (std::int64_t first = 0; first < layers; first += step) {
    const std::int64_t last = std::min(layers, first + step);
    // Layers [first, last) lie between padded slices first and last, volume slices first − 1
    // to last − 1; gradients read one more on each side (two kept for margin).
    const std::int64_t need = std::min(size.nz, last + 2);
    if (need > computed) {
      const std::int64_t c0 = std::max<std::int64_t>(0, computed - halo);
      const std::int64_t c1 = std::min(size.nz, need + halo);
      d2.resize(static_cast<std::size_t>((c1 - c0) * plane));
      constexpr float kFar = std::numeric_limits<float>::infinity();
      field.visit([&](const auto* values) {
        const auto* from = values + c0 * plane;
        for (std::size_t v = 0; v < d2.size(); ++v) d2[v] = from[v] >= iso ? kFar : 0.0f;
      });
      squared_distance_transform_slab(d2, {size.nx, size.ny, c1 - c0}, c0, size.nz, spacing,
                                      /*seeds_beyond_border=*/true, options.threads);
      s.band_samples += field_slices(d2.data() + (computed - c0) * plane,
                                     distance.slice(computed), computed, need, size, band);
      computed = need;
    }
    piece = detail::extract_layers(distance, level_f, extract, first, last,
                                   /*defer_normals=*/false, -1.0, &piece);
    // Stitch: the piece's first shared_vertices vertices are the previous piece's top slice.
    const std::size_t shared = piece.shared_vertices;
    const std::size_t base = inner.positions.size();
    inner.positions.insert(inner.positions.end(),
                           piece.mesh.positions.begin() + static_cast<std::ptrdiff_t>(shared),
                           piece.mesh.positions.end());
    if (extract.vertex_normals) {
      inner.normals.insert(inner.normals.end(),
                           piece.mesh.normals.begin() + static_cast<std::ptrdiff_t>(shared),
                           piece.mesh.normals.end());
    }
    for (const auto& t : piece.mesh.triangles) {
      std::array<std::uint32_t, 3> triangle{};
      for (int c = 0; c < 3; ++c) {
        triangle[c] = static_cast<std::uint32_t>(t[c] < shared ? below + t[c] : base - shared + t[c]);
      }
      inner.triangles.push_back(triangle);
    }
    below = base + piece.top_first - shared;
    // Slices below last − 3 are read by no later piece.
    const std::int64_t keep = std::max<std::int64_t>(released, std::min(computed, last - 3));
    if (keep > released) {
      const auto bytes = static_cast<std::size_t>((keep - released) * plane) * sizeof(float);
      detail::release_whole_pages(distance.slice(released), bytes);
      released = keep;
    }
  }
  return inner;
}

}  // namespace

TriangleMesh extract_inner_wall(const Volume& field, float iso, const TriangleMesh& outer,
                                const InnerWallOptions& options, InnerWallStats* stats) {
  assert(options.wall_mm > 0);
  InnerWallStats local;
  InnerWallStats& s = stats != nullptr ? *stats : local;
  s = {};
  const IndexToPatient& geometry = field.geometry();
  const std::array<double, 3> spacing = {geometry.spacing(0), geometry.spacing(1),
                                         geometry.spacing(2)};

  // The band (step 3).
  // Not a structured binding: Clang 14 (the fuzz build) cannot capture one in a lambda.
  const auto stretch = stretch_bounds(geometry);
  const double sigma_min = stretch[0], sigma_max = stretch[1];
  const Point diagonal_vector = {
      geometry.axes[0][0] + geometry.axes[1][0] + geometry.axes[2][0],
      geometry.axes[0][1] + geometry.axes[1][1] + geometry.axes[2][1],
      geometry.axes[0][2] + geometry.axes[1][2] + geometry.axes[2][2]};
  // The longest cube diagonal of a sheared grid is one of the four ±; bound it by the sum.
  const double diagonal = std::max(std::sqrt(dot(diagonal_vector, diagonal_vector)),
                                   std::sqrt(spacing[0] * spacing[0] + spacing[1] * spacing[1] +
                                             spacing[2] * spacing[2]) *
                                       sigma_max);
  const double wall = options.wall_mm, m = options.outer_deviation_mm;
  Band band;
  band.lo = (wall - m) / sigma_max;                                           // below: F < wall surely
  band.hi = (wall + diagonal * diagonal / (8 * wall) + diagonal + m) / sigma_min;  // above: F > level
  // Out of the band, F's lower bound σ_min·D − r − m (at least 0).
  band.sigma_min = sigma_min;
  band.diagonal = diagonal;
  band.deviation = m;
  band.search = band.hi * sigma_max + diagonal;
  band.geometry = &geometry;
  band.outer = &outer;
  band.threads = options.threads;

  // 4. The wall: samples with F >= wall are inside the field's iso-surface, which is the
  // hollow's boundary wound outward from the hollow; reversed, it faces into it.
  ExtractOptions extract;
  extract.close_borders = true;
  extract.threads = options.threads;
  extract.vertex_normals = !outer.normals.empty();  // the joined surface has them or not
  // Extracted slightly deeper than the wall: across a cube, linear interpolation of F (a
  // distance to a convex bend is convex) errs by up to about r² / (8 · wall), the chord
  // error over the cube's diagonal r, toward the outer wall.
  const double level = wall + diagonal * diagonal / (8 * wall);
  // A value that can differ between the slabs' distances and the whole volume's is deeper
  // than `reach` (D, mm): above the band, and more than a cube diagonal (a crossing cube's
  // corners, its faces' decider) plus a gradient step from any sample below the level.
  const double reach = band.hi + 4 * diagonal + std::max({spacing[0], spacing[1], spacing[2]});
  TriangleMesh inner =
      options.fill_enclosed || options.slab_layers == 0
          ? whole_volume_wall(field, iso, options, band, extract, level, s)
          : slab_wall(field, iso, options, band, extract, level, reach, s);
  if (inner.empty()) return inner;
  to_patient(inner, geometry);
  for (auto& t : inner.triangles) std::swap(t[1], t[2]);
  for (auto& n : inner.normals) n = {-n[0], -n[1], -n[2]};

  // 5. Components (through shared vertices), each kept or dropped whole.
  std::vector<std::uint32_t> parent(inner.positions.size());
  for (std::uint32_t v = 0; v < parent.size(); ++v) parent[v] = v;
  for (const auto& t : inner.triangles) {
    for (int e = 1; e < 3; ++e) {
      const std::uint32_t a = find_root(parent, t[0]), b = find_root(parent, t[e]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  std::vector<std::vector<std::uint32_t>> triangles_of;
  {
    std::vector<std::uint32_t> root_label(inner.positions.size(),
                                          std::numeric_limits<std::uint32_t>::max());
    for (std::uint32_t t = 0; t < inner.triangles.size(); ++t) {
      const std::uint32_t root = find_root(parent, inner.triangles[t][0]);
      if (root_label[root] == std::numeric_limits<std::uint32_t>::max()) {
        root_label[root] = static_cast<std::uint32_t>(triangles_of.size());
        triangles_of.emplace_back();
      }
      triangles_of[root_label[root]].push_back(t);
    }
  }
  s.components = triangles_of.size();
  const double min_hollow = wall * wall * wall;
  TriangleMesh kept;
  std::vector<std::uint32_t> new_index(inner.positions.size(),
                                       std::numeric_limits<std::uint32_t>::max());
  std::optional<RayParity> outer_parity;  // built when a component is first tested
  for (const auto& component : triangles_of) {
    const double volume = signed_volume(inner, component);  // < 0: a hollow, > 0: an island
    if (volume < 0 && -volume < min_hollow) {
      ++s.dropped_small;
      continue;
    }
    // Inside the outer surface or not: the walls do not cross, so one vertex decides; three
    // (first, middle, last triangle) vote, against a ray through an edge.
    if (!outer_parity) outer_parity.emplace(outer);
    int inside = 0;
    for (std::size_t pick : {std::size_t{0}, component.size() / 2, component.size() - 1}) {
      inside +=
          outer_parity->inside(to_point(inner.positions[inner.triangles[component[pick]][0]])) ? 1
                                                                                                : 0;
    }
    if (inside < 2) {
      ++s.dropped_outside;
      continue;
    }
    s.hollow_volume_mm3 -= volume;
    for (std::uint32_t t : component) {
      std::array<std::uint32_t, 3> triangle{};
      for (int c = 0; c < 3; ++c) {
        const std::uint32_t v = inner.triangles[t][c];
        if (new_index[v] == std::numeric_limits<std::uint32_t>::max()) {
          new_index[v] = static_cast<std::uint32_t>(kept.positions.size());
          kept.positions.push_back(inner.positions[v]);
          if (extract.vertex_normals) kept.normals.push_back(inner.normals[v]);
        }
        triangle[c] = new_index[v];
      }
      kept.triangles.push_back(triangle);
    }
  }
  return kept;
}

}  // namespace typemerge::core
