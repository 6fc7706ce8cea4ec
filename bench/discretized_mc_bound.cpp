// discretized_mc_bound: the best reduction the "marching cubes speed" route could give on a
// series — discretized marching cubes (Montani, Scateni & Scopigno 1994: vertices at edge
// midpoints, so facets fall on a few planes, and coplanar facets merged during the scan) —
// beside our marching cubes and type merging (issue 14 asks for tm ≤ 50 % of mc at 300 HU and
// ≤ 25 % at −500 HU, at flying edges' speed).
//
//   discretized_mc_bound --series DIR [--iso 300,-500] [--spacing refuse|resample]
//
// How the bound is computed (an estimate that favours discretized MC):
//  * the volume is binarised at iso (sample >= iso → 1, as marching cubes classifies) and
//    extracted at 0.5 by our consistent marching cubes in index space: the same cube
//    configurations as mc at iso, every vertex an edge midpoint;
//  * triangles are grouped into regions: edge-connected triangles on one exact plane (the
//    plane's integer normal and offset from doubled coordinates, its orientation kept);
//  * an ideal merge re-triangulates each region from its boundary and drops every vertex it
//    can: it keeps only the boundary vertices in three or more regions, those where the
//    region's boundary turns, and pinched ones (the boundary passes twice). A region whose
//    boundary keeps k vertex occurrences and whose Euler characteristic is χ then needs k − 2χ
//    triangles (a polygon with h holes: k + 2h − 2).
// The sum ignores triangle shape, crossings and the half-voxel terraces the midpoints add, so
// no coplanar merge of the discretized surface does better.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include "core/marching_cubes.h"
#include "core/type_merging.h"
#include "core/union_find.h"
#include "default_series.h"
#include "list_argument.h"

namespace {

using namespace typemerge;
using I3 = std::array<std::int64_t, 3>;

I3 doubled(const std::array<float, 3>& p) {
  return {std::llround(2.0 * p[0]), std::llround(2.0 * p[1]), std::llround(2.0 * p[2])};
}
I3 sub(const I3& a, const I3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
I3 cross(const I3& a, const I3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
bool is_zero(const I3& a) { return a[0] == 0 && a[1] == 0 && a[2] == 0; }

// A triangle's plane: its normal divided by the gcd of its components (orientation kept, so
// the two sides of a thin plate are different planes) and its offset along that normal.
std::array<std::int64_t, 4> plane_key(const I3& a, const I3& b, const I3& c) {
  I3 n = cross(sub(b, a), sub(c, a));
  const std::int64_t g = std::gcd(std::gcd(std::llabs(n[0]), std::llabs(n[1])), std::llabs(n[2]));
  if (g > 0) n = {n[0] / g, n[1] / g, n[2] / g};
  return {n[0], n[1], n[2], n[0] * a[0] + n[1] * a[1] + n[2] * a[2]};
}

struct Bound {
  std::size_t triangles = 0;  // discretized marching cubes
  std::size_t regions = 0;
  std::size_t merged = 0;  // the ideal coplanar merge
};

Bound coplanar_merge_bound(const core::TriangleMesh& mesh) {
  const auto& tris = mesh.triangles;
  const std::size_t n_tri = tris.size();
  const std::size_t n_vert = mesh.positions.size();
  std::vector<I3> p(n_vert);
  for (std::size_t v = 0; v < n_vert; ++v) p[v] = doubled(mesh.positions[v]);
  std::vector<std::array<std::int64_t, 4>> plane(n_tri);
  for (std::size_t t = 0; t < n_tri; ++t) {
    plane[t] = plane_key(p[tris[t][0]], p[tris[t][1]], p[tris[t][2]]);
  }

  // Directed edges (from, to, triangle), sorted so that an edge's twin (to, from) is found by
  // binary search: the surface is closed and manifold, so every edge has exactly one.
  struct Edge {
    std::uint32_t from, to, tri;
    bool operator<(const Edge& o) const { return from != o.from ? from < o.from : to < o.to; }
  };
  std::vector<Edge> edges;
  edges.reserve(3 * n_tri);
  for (std::uint32_t t = 0; t < n_tri; ++t) {
    for (int e = 0; e < 3; ++e) edges.push_back({tris[t][e], tris[t][(e + 1) % 3], t});
  }
  std::sort(edges.begin(), edges.end());
  auto twin = [&](const Edge& e) -> const Edge& {
    const auto it = std::lower_bound(edges.begin(), edges.end(), Edge{e.to, e.from, 0});
    if (it == edges.end() || it->from != e.to || it->to != e.from) {
      std::fprintf(stderr, "surface is not closed and manifold\n");
      std::exit(1);
    }
    return *it;
  };

  std::vector<std::uint32_t> parent(n_tri);
  std::iota(parent.begin(), parent.end(), 0u);
  for (const Edge& e : edges) {
    const Edge& o = twin(e);
    if (plane[e.tri] == plane[o.tri]) {
      parent[core::find_root(parent, e.tri)] = core::find_root(parent, o.tri);
    }
  }
  std::vector<std::uint32_t> region(n_tri);
  for (std::uint32_t t = 0; t < n_tri; ++t) region[t] = core::find_root(parent, t);

  // Regions at each vertex, and per region its distinct vertices (for χ).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> vertex_region;  // (vertex, region)
  vertex_region.reserve(3 * n_tri);
  for (std::uint32_t t = 0; t < n_tri; ++t) {
    for (std::uint32_t v : tris[t]) vertex_region.push_back({v, region[t]});
  }
  std::sort(vertex_region.begin(), vertex_region.end());
  vertex_region.erase(std::unique(vertex_region.begin(), vertex_region.end()),
                      vertex_region.end());
  std::vector<std::uint32_t> regions_at(n_vert, 0);
  std::vector<std::int64_t> chi(n_tri, 0);  // by region root: V − E + F
  for (const auto& [v, r] : vertex_region) {
    ++regions_at[v];
    ++chi[r];
  }

  // Boundary edges of each region (the twin lies in another region), by (region, from) and by
  // (region, to).
  struct Border {
    std::uint32_t r, a, b;  // region, from, to
  };
  std::vector<Border> out_edges, in_edges;
  std::vector<std::int64_t> faces(n_tri, 0), border_count(n_tri, 0);
  for (std::uint32_t t = 0; t < n_tri; ++t) ++faces[region[t]];
  for (const Edge& e : edges) {
    if (region[twin(e).tri] == region[e.tri]) continue;
    out_edges.push_back({region[e.tri], e.from, e.to});
    ++border_count[region[e.tri]];
  }
  in_edges = out_edges;
  std::sort(out_edges.begin(), out_edges.end(),
            [](const Border& x, const Border& y) { return x.r != y.r ? x.r < y.r : x.a < y.a; });
  std::sort(in_edges.begin(), in_edges.end(),
            [](const Border& x, const Border& y) { return x.r != y.r ? x.r < y.r : x.b < y.b; });

  Bound bound;
  bound.triangles = n_tri;
  std::vector<std::int64_t> kept(n_tri, 0);
  for (std::size_t i = 0; i < out_edges.size(); ++i) {
    const Border& e = out_edges[i];  // its start vertex e.a is the occurrence judged
    const bool pinched = (i > 0 && out_edges[i - 1].r == e.r && out_edges[i - 1].a == e.a) ||
                         (i + 1 < out_edges.size() && out_edges[i + 1].r == e.r &&
                          out_edges[i + 1].a == e.a);
    bool keep = pinched || regions_at[e.a] >= 3;
    if (!keep) {
      const auto in = std::lower_bound(
          in_edges.begin(), in_edges.end(), e,
          [](const Border& x, const Border& y) { return x.r != y.r ? x.r < y.r : x.b < y.a; });
      keep = !is_zero(cross(sub(p[e.a], p[in->a]), sub(p[e.b], p[e.a])));
    }
    kept[e.r] += keep ? 1 : 0;
  }
  for (std::uint32_t r = 0; r < n_tri; ++r) {
    if (faces[r] == 0) continue;
    ++bound.regions;
    const std::int64_t edges_in_region = (3 * faces[r] + border_count[r]) / 2;
    const std::int64_t euler = chi[r] - edges_in_region + faces[r];
    bound.merged += static_cast<std::size_t>(std::max<std::int64_t>(1, kept[r] - 2 * euler));
  }
  return bound;
}

int usage() {
  std::fprintf(stderr,
               "usage: discretized_mc_bound --series DIR [--iso 300,-500] "
               "[--spacing refuse|resample]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string series_dir, isos = "300,-500", spacing = "refuse";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--series") series_dir = value;
    else if (key == "--iso") isos = value;
    else if (key == "--spacing") spacing = value;
    else return usage();
  }
  if (series_dir.empty() || argc % 2 == 0) return usage();
  if (spacing != "refuse" && spacing != "resample") return usage();

  const auto loaded = bench::load_default_series(series_dir, spacing == "resample");
  if (!loaded) return 1;
  const core::Volume& volume = *loaded;
  const core::VolumeSize size = volume.size();
  std::printf("%s: %lld x %lld x %lld\n", series_dir.c_str(), static_cast<long long>(size.nx),
              static_cast<long long>(size.ny), static_cast<long long>(size.nz));
  std::printf("%8s %11s %11s %11s %9s %11s %9s\n", "iso HU", "mc", "tm", "discMC", "regions",
              "discMC best", "best/mc");
  for (const std::string& text : bench::split(isos)) {
    const float iso = std::stof(text);
    const core::TriangleMesh mc = core::extract_isosurface(volume, iso);
    const core::TriangleMesh tm = core::extract_type_merged(volume, iso);
    core::Volume binary(size, core::IndexToPatient{});  // index space: midpoints are exact
    volume.visit([&](const auto* samples) {
      core::Samples& out = binary.samples();
      for (std::size_t s = 0; s < out.size(); ++s) out[s] = samples[s] >= iso ? 1.0f : 0.0f;
    });
    const Bound bound = coplanar_merge_bound(core::extract_isosurface(binary, 0.5f));
    std::printf("%8g %11zu %11zu %11zu %9zu %11zu %8.1f%%\n", static_cast<double>(iso),
                mc.triangles.size(), tm.triangles.size(), bound.triangles, bound.regions,
                bound.merged,
                100.0 * static_cast<double>(bound.merged) /
                    static_cast<double>(std::max<std::size_t>(1, mc.triangles.size())));
  }
  return 0;
}
