// Tests of extract_isosurface, up the oracle ladder: exact output for single cubes; all 256
// configurations, alone and in random neighbourhoods; random noise (watertight, manifold, and
// identical to a slow per-cube reference); analytic volumes (sphere, torus, box); ties on
// integer data; the classic mode's holes; statistics; to_patient on an extracted surface.
#include "core/marching_cubes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <vector>

#include "core/cube_tables.h"
#include "core/mesh_checks.h"
#include "test_volumes.h"

namespace typemerge::core {
namespace {

using test::noise_volume;
using test::sample_volume;
using test::set_cube;
using test::sphere_volume;

const ExtractOptions kOpen{.close_borders = false};
const ExtractOptions kClosed{.close_borders = true};
const ExtractOptions kClassic{.close_borders = true, .mode = ExtractOptions::Mode::classic};

// ---- A slow, independent reference ----------------------------------------------------------
//
// Per cube: states from a padded accessor, the face decisions by the spec's formula (saddle
// value with the division), triangulate_cube, and vertices named by lattice key in a map. The
// extractor under test must give the same triangles (compared by key, so vertex numbering and
// positions do not matter) and exactly one vertex per key.

using Key = std::array<std::int64_t, 4>;  // lattice edge (x, y, z, axis) or cube (x, y, z, 3 + k)
using KeyTriangle = std::array<Key, 3>;

KeyTriangle canonical(KeyTriangle t) {
  // Rotate so the smallest key comes first; keeps the orientation.
  const auto first = std::min_element(t.begin(), t.end());
  std::rotate(t.begin(), first, t.end());
  return t;
}

std::vector<KeyTriangle> reference_triangles(const Volume& volume, float iso, bool close_borders,
                                             bool consistent) {
  const VolumeSize& n = volume.size();
  auto value = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    if (i < 0 || j < 0 || k < 0 || i >= n.nx || j >= n.ny || k >= n.nz) {
      return -std::numeric_limits<float>::infinity();
    }
    return volume.at(i, j, k);
  };
  const std::int64_t lo = close_borders ? -1 : 0;
  const std::int64_t hi = close_borders ? 0 : -1;  // last cube = size − 1 + hi
  std::vector<KeyTriangle> out;
  for (std::int64_t z = lo; z < n.nz + hi; ++z) {
    for (std::int64_t y = lo; y < n.ny + hi; ++y) {
      for (std::int64_t x = lo; x < n.nx + hi; ++x) {
        float v[8];
        unsigned c = 0;
        for (int i = 0; i < 8; ++i) {
          const auto& o = kCubeVertexOffset[i];
          v[i] = value(x + o[0], y + o[1], z + o[2]);
          if (v[i] >= iso) c |= 1u << i;
        }
        unsigned joined = 0;
        for (int f = 0; f < 6; ++f) {
          if (((kCubeAmbiguousFaces[c] >> f) & 1u) == 0) continue;
          const auto& fv = kCubeFaceVertices[f];
          const double a = v[fv[0]], b = v[fv[1]], cc = v[fv[2]], d = v[fv[3]];
          const double saddle = (a * cc - b * d) / (a + cc - b - d);
          const bool inside_joined = saddle >= iso;  // the bilinear saddle is inside
          if (consistent ? inside_joined : c >= 128) joined |= 1u << f;
        }
        const CubeCase cube_case = triangulate_cube(c, joined);
        auto key = [&](int local) -> Key {
          if (local >= kFirstCentroid) return {x, y, z, 3 + local - kFirstCentroid};
          const LatticeEdge& l = kCubeEdgeLattice[local];
          return {x + l.offset[0], y + l.offset[1], z + l.offset[2], l.axis};
        };
        for (int t = 0; t < cube_case.triangle_count; ++t) {
          const auto& tri = cube_case.triangles[t];
          out.push_back(canonical({key(tri[0]), key(tri[1]), key(tri[2])}));
        }
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Names each vertex of an extracted mesh by its lattice key, from its position: an edge
// vertex has two integral coordinates (it lies strictly inside its edge), a centre vertex
// lies strictly inside its cube and is numbered in creation order within the cube.
std::vector<Key> keys_of(const TriangleMesh& mesh) {
  std::vector<Key> keys;
  std::map<std::array<std::int64_t, 3>, int> centres_in_cube;
  for (const auto& p : mesh.positions) {
    std::array<std::int64_t, 3> cell{};
    int fractional = 0;
    int axis = 0;
    for (int a = 0; a < 3; ++a) {
      const float f = std::floor(p[a]);
      cell[a] = static_cast<std::int64_t>(f);
      if (f != p[a]) {
        ++fractional;
        axis = a;
      }
    }
    if (fractional == 1) {
      keys.push_back({cell[0], cell[1], cell[2], axis});
    } else {
      keys.push_back({cell[0], cell[1], cell[2], 3 + centres_in_cube[cell]++});
    }
  }
  return keys;
}

void expect_matches_reference(const Volume& volume, float iso, const ExtractOptions& options) {
  const TriangleMesh mesh = extract_isosurface(volume, iso, options);
  const std::vector<Key> keys = keys_of(mesh);
  std::vector<Key> distinct = keys;
  std::sort(distinct.begin(), distinct.end());
  EXPECT_EQ(std::unique(distinct.begin(), distinct.end()), distinct.end())
      << "two vertices on one lattice edge";
  std::vector<KeyTriangle> got;
  for (const auto& t : mesh.triangles)
    got.push_back(canonical({keys[t[0]], keys[t[1]], keys[t[2]]}));
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, reference_triangles(volume, iso, options.close_borders,
                                     options.mode == ExtractOptions::Mode::consistent));
}

// Whether sample (i, j, k) is inside; samples beyond the volume (the padding) are outside.
bool inside_or_padding(const Volume& volume, float iso, std::int64_t i, std::int64_t j,
                       std::int64_t k) {
  const VolumeSize& n = volume.size();
  if (i < 0 || j < 0 || k < 0 || i >= n.nx || j >= n.ny || k >= n.nz) return false;
  return volume.at(i, j, k) >= iso;
}

// Number of lattice edges with a sign change, padding included when closing borders: with
// vertex sharing this is exactly the number of edge vertices.
std::size_t cut_edge_count(const Volume& volume, float iso, bool close_borders) {
  const VolumeSize& n = volume.size();
  auto inside = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return inside_or_padding(volume, iso, i, j, k);
  };
  const std::int64_t lo = close_borders ? -1 : 0;
  const std::int64_t pad = close_borders ? 1 : 0;
  std::size_t count = 0;
  for (std::int64_t k = lo; k < n.nz + pad; ++k) {
    for (std::int64_t j = lo; j < n.ny + pad; ++j) {
      for (std::int64_t i = lo; i < n.nx + pad; ++i) {
        if (i + 1 < n.nx + pad && inside(i, j, k) != inside(i + 1, j, k)) ++count;
        if (j + 1 < n.ny + pad && inside(i, j, k) != inside(i, j + 1, k)) ++count;
        if (k + 1 < n.nz + pad && inside(i, j, k) != inside(i, j, k + 1)) ++count;
      }
    }
  }
  return count;
}

// Number of cubes with corners on both sides of iso (padding included when closing borders).
std::size_t boundary_cube_count(const Volume& volume, float iso, bool close_borders) {
  const VolumeSize& n = volume.size();
  const std::int64_t first = close_borders ? -1 : 0;  // first cube origin
  const std::int64_t end = close_borders ? 0 : -1;    // one past the last: n + end
  std::size_t count = 0;
  for (std::int64_t k = first; k < n.nz + end; ++k) {
    for (std::int64_t j = first; j < n.ny + end; ++j) {
      for (std::int64_t i = first; i < n.nx + end; ++i) {
        int corners = 0;
        for (int c = 0; c < 8; ++c) {
          corners += inside_or_padding(volume, iso, i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
        }
        if (corners != 0 && corners != 8) ++count;
      }
    }
  }
  return count;
}

// ---- Single cubes ---------------------------------------------------------------------------

//   y                 v0 inside (value 1), the other seven 0, iso 0.5, borders open:
//   |  e3 (0,.5,0)    one triangle through the three edge midpoints around v0,
//   | /  \            wound so its normal (+,+,+) points away from v0.
//   +----e0--- x
//  / e8
// z
TEST(MarchingCubes, SingleCornerIsExact) {
  Volume volume({2, 2, 2}, {});
  volume.at(0, 0, 0) = 1.0f;
  const TriangleMesh mesh = extract_isosurface(volume, 0.5f, kOpen);
  // Vertex order: slice x-edges, slice y-edges, then z-edges.
  using P = std::array<float, 3>;
  EXPECT_EQ(mesh.positions, (std::vector<P>{{0.5f, 0, 0}, {0, 0.5f, 0}, {0, 0, 0.5f}}));
  EXPECT_EQ(mesh.triangles, (std::vector<std::array<std::uint32_t, 3>>{{0, 1, 2}}));
  // Gradient at v0 (one-sided) is (−1,−1,−1), at v1 (−1,0,0); halfway: −(−1,−.5,−.5).
  const float s = 1.0f / std::sqrt(1.5f);
  EXPECT_NEAR(mesh.normals[0][0], s, 1e-6);
  EXPECT_NEAR(mesh.normals[0][1], 0.5f * s, 1e-6);
  EXPECT_NEAR(mesh.normals[0][2], 0.5f * s, 1e-6);
  EXPECT_NEAR(mesh.normals[2][2], s, 1e-6);
  EXPECT_GT(check_mesh(mesh).volume, 0.0);
}

TEST(MarchingCubes, SingleVoxelClosesToAnOctahedron) {
  // One inside sample, borders closed: each of the 8 padded cubes around it cuts off one
  // corner, the 6 vertices sit kEdgeMargin out along ±x, ±y, ±z.
  Volume volume({1, 1, 1}, {});
  volume.at(0, 0, 0) = 5.0f;
  const TriangleMesh mesh = extract_isosurface(volume, 1.0f, kClosed);
  const MeshCheck c = check_mesh(mesh);
  EXPECT_TRUE(c.closed_manifold());
  EXPECT_EQ(c.vertices, 6u);
  EXPECT_EQ(c.triangles, 8u);
  EXPECT_EQ(c.euler_characteristic, 2);
  const double d = kEdgeMargin;
  EXPECT_NEAR(c.volume, 4.0 / 3.0 * d * d * d, 1e-12);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto& p = mesh.positions[v];
    const auto& n = mesh.normals[v];
    EXPECT_NEAR(std::abs(p[0]) + std::abs(p[1]) + std::abs(p[2]), d, 1e-7);
    EXPECT_NEAR(n[0] * p[0] + n[1] * p[1] + n[2] * p[2], d, 1e-7);  // border normal, outward
  }
}

TEST(MarchingCubes, EmptyAndTrivialVolumes) {
  EXPECT_TRUE(extract_isosurface(Volume{}, 0.0f, kClosed).empty());
  Volume flat({4, 4, 1}, {});
  EXPECT_TRUE(extract_isosurface(flat, 0.5f, kOpen).empty());    // no cube at all
  EXPECT_TRUE(extract_isosurface(flat, 0.5f, kClosed).empty());  // nothing inside
  EXPECT_TRUE(extract_isosurface(flat, -1.0f, kOpen).empty());   // everything inside, open
  const MeshCheck slab = check_mesh(extract_isosurface(flat, -1.0f, kClosed));
  EXPECT_TRUE(slab.closed_manifold());
  EXPECT_EQ(slab.euler_characteristic, 2);
}

TEST(MarchingCubes, AllConfigurationsOfOneCubeAreClosedSpheres) {
  std::mt19937 rng(1);
  for (unsigned c = 0; c < 256; ++c) {
    for (int trial = 0; trial < 40; ++trial) {
      Volume volume({2, 2, 2}, {});
      set_cube(volume, c, 0, 0, 0, rng);
      AmbiguityStats stats;
      ExtractOptions options = kClosed;
      options.stats = &stats;
      const TriangleMesh mesh = extract_isosurface(volume, 0.0f, options);
      const MeshCheck check = check_mesh(mesh);
      SCOPED_TRACE(testing::Message() << "index " << c << " trial " << trial);
      ASSERT_TRUE(check.closed_manifold());
      // Every inside component of a closed-off cube is a ball.
      ASSERT_EQ(check.euler_characteristic, 2 * static_cast<std::int64_t>(check.components));
      ASSERT_EQ(check.components == 0, c == 0);
      if (c != 0) {
        ASSERT_GT(check.volume, 0.0);
      }
      ASSERT_EQ(check.vertices, cut_edge_count(volume, 0.0f, true) + stats.centroid_vertices);
    }
  }
}

TEST(MarchingCubes, AllConfigurationsInRandomNeighbourhoods) {
  std::mt19937 rng(2);
  for (unsigned c = 0; c < 256; ++c) {
    for (int trial = 0; trial < 8; ++trial) {
      Volume volume = noise_volume(4, 4, 4, static_cast<unsigned>(rng()));
      for (float& v : volume.samples()) v -= 0.5f;
      set_cube(volume, c, 1, 1, 1, rng);
      SCOPED_TRACE(testing::Message() << "index " << c << " trial " << trial);
      AmbiguityStats stats;
      ExtractOptions options = kClosed;
      options.stats = &stats;
      const TriangleMesh mesh = extract_isosurface(volume, 0.0f, options);
      const MeshCheck check = check_mesh(mesh);
      ASSERT_TRUE(check.closed_manifold());
      ASSERT_GE(check.volume, 0.0);
      ASSERT_EQ(check.vertices, cut_edge_count(volume, 0.0f, true) + stats.centroid_vertices);
      if (trial == 0) expect_matches_reference(volume, 0.0f, kClosed);
    }
  }
}

// ---- Noise: many ambiguous faces -----------------------------------------------------------

TEST(MarchingCubes, NoiseIsWatertightAndManifold) {
  std::size_t ambiguous_cubes = 0;
  std::size_t centroids = 0;
  for (unsigned seed = 0; seed < 60; ++seed) {
    const Volume volume = noise_volume(12, 12, 12, seed);
    AmbiguityStats stats;
    ExtractOptions options = kClosed;
    options.stats = &stats;
    const TriangleMesh mesh = extract_isosurface(volume, 0.5f, options);
    const MeshCheck check = check_mesh(mesh);
    SCOPED_TRACE(testing::Message() << "seed " << seed);
    EXPECT_TRUE(check.closed_manifold())
        << check.boundary_edges << " boundary, " << check.non_manifold_edges << " non-manifold, "
        << check.inconsistent_edges << " inconsistent, " << check.non_manifold_vertices
        << " non-manifold vertices, " << check.degenerate_triangles << " degenerate";
    EXPECT_GT(check.volume, 0.0);
    EXPECT_EQ(check.vertices, cut_edge_count(volume, 0.5f, true) + stats.centroid_vertices);
    EXPECT_EQ(mesh.positions.size(), check.vertices);  // no unused vertex is created
    ambiguous_cubes += stats.boundary_cubes - stats.cubes_with_ambiguous_faces[0];
    centroids += stats.centroid_vertices;
  }
  EXPECT_GT(ambiguous_cubes, 1000u);  // the test exercised the decider
  EXPECT_GT(centroids, 0u);           // and the centre-vertex fallback
}

// A recorded cube's loop count is the number of connected pieces its triangles form (type
// merging trusts a count of one to skip its union-find), with every face decision.
TEST(MarchingCubes, EachRecordedCubeCountsTheLoopsItsTrianglesForm) {
  std::array<std::size_t, 5> cubes_by_loops{};
  for (unsigned seed = 0; seed < 20; ++seed) {
    const Volume volume = noise_volume(12, 12, 12, seed);
    std::vector<BoundaryCube> cubes;
    ExtractOptions options = kClosed;
    options.cubes = &cubes;
    const TriangleMesh mesh = extract_isosurface(volume, 0.5f, options);
    for (std::size_t k = 0; k < cubes.size(); ++k) {
      const std::uint32_t end =
          k + 1 < cubes.size() ? cubes[k + 1].first_triangle
                               : static_cast<std::uint32_t>(mesh.triangles.size());
      std::map<std::uint32_t, std::uint32_t> parent;
      auto find = [&parent](std::uint32_t v) {
        while (parent.at(v) != v) v = parent.at(v);
        return v;
      };
      for (std::uint32_t t = cubes[k].first_triangle; t < end; ++t) {
        for (std::uint32_t v : mesh.triangles[t]) parent.emplace(v, v);
        const std::uint32_t root = find(mesh.triangles[t][0]);
        parent[find(mesh.triangles[t][1])] = root;
        parent[find(mesh.triangles[t][2])] = root;
      }
      std::size_t pieces = 0;
      for (const auto& [v, p] : parent) pieces += v == p ? 1 : 0;
      ASSERT_EQ(cubes[k].loops, pieces) << "seed " << seed << ", cube index "
                                        << int{cubes[k].index};
      ++cubes_by_loops[std::min<std::size_t>(pieces, 4)];
    }
  }
  EXPECT_GT(cubes_by_loops[1], 1000u);
  EXPECT_GT(cubes_by_loops[2], 100u);  // noise has cubes of several loops, too
  EXPECT_EQ(cubes_by_loops[0], 0u);
}

TEST(MarchingCubes, NoiseMatchesTheSlowReference) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    SCOPED_TRACE(testing::Message() << "seed " << seed);
    const Volume volume = noise_volume(9, 10, 11, seed);
    expect_matches_reference(volume, 0.5f, kClosed);
    expect_matches_reference(volume, 0.5f, kOpen);
    expect_matches_reference(volume, 0.5f, kClassic);
  }
}

// The extractor steps over 8 bytes at a time where rows hold no cut (word scans): long
// inside and outside runs with isolated cuts at every offset within a word and rows of every
// length mod 8 must give exactly the reference's triangles.
TEST(MarchingCubes, LongRunsWithIsolatedCutsMatchTheSlowReference) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (std::int64_t nx = 30; nx <= 41; ++nx) {
    SCOPED_TRACE(testing::Message() << "nx " << nx);
    // A slab-like "body" (inside between random ends per row), specks of the other state
    // inside and outside it, and values spread around the iso value near the surface.
    Volume volume({nx, 7, 6}, IndexToPatient{});
    for (std::int64_t k = 0; k < 6; ++k) {
      for (std::int64_t j = 0; j < 7; ++j) {
        const auto first = static_cast<std::int64_t>(uniform(rng) * 10.0f);
        const auto last = nx - 1 - static_cast<std::int64_t>(uniform(rng) * 10.0f);
        for (std::int64_t i = 0; i < nx; ++i) {
          const bool body = k > 0 && k < 5 && j > 0 && j < 6 && i >= first && i <= last;
          const bool speck = uniform(rng) < 0.04f;
          const bool inside = body != speck;
          volume.at(i, j, k) = inside ? 0.5f + 0.5f * uniform(rng) : 0.49f * uniform(rng);
        }
      }
    }
    expect_matches_reference(volume, 0.5f, kClosed);
    expect_matches_reference(volume, 0.5f, kOpen);
    expect_matches_reference(volume, 0.5f, kClassic);
    for (const bool close : {true, false}) {
      AmbiguityStats stats;
      ExtractOptions options{.close_borders = close};
      options.stats = &stats;
      extract_isosurface(volume, 0.5f, options);
      EXPECT_EQ(stats.boundary_cubes, boundary_cube_count(volume, 0.5f, close)) << close;
    }
  }
}

TEST(MarchingCubes, OpenBordersLeaveBoundaryOnlyOnTheBorder) {
  for (unsigned seed = 0; seed < 20; ++seed) {
    const Volume volume = noise_volume(12, 12, 12, seed);
    const TriangleMesh mesh = extract_isosurface(volume, 0.5f, kOpen);
    const MeshCheck check = check_mesh(mesh);
    EXPECT_EQ(check.non_manifold_edges, 0u);
    EXPECT_EQ(check.inconsistent_edges, 0u);
    EXPECT_EQ(check.non_manifold_vertices, 0u);
    EXPECT_EQ(check.degenerate_triangles, 0u);
    EXPECT_GT(check.boundary_edges, 0u);
    // Both ends of every boundary edge on one border plane.
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;
    for (const auto& t : mesh.triangles) {
      for (int k = 0; k < 3; ++k) {
        ++uses[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
      }
    }
    for (const auto& [edge, count] : uses) {
      if (count != 1) continue;
      const auto& p = mesh.positions[edge.first];
      const auto& q = mesh.positions[edge.second];
      bool on_border = false;
      for (int a = 0; a < 3; ++a) {
        for (float plane : {0.0f, 11.0f}) on_border |= p[a] == plane && q[a] == plane;
      }
      EXPECT_TRUE(on_border);
    }
  }
}

TEST(MarchingCubes, ClassicModeLeavesHolesOnNoise) {
  std::size_t seeds_with_holes = 0;
  for (unsigned seed = 0; seed < 20; ++seed) {
    const Volume volume = noise_volume(12, 12, 12, seed);
    const MeshCheck classic = check_mesh(extract_isosurface(volume, 0.5f, kClassic));
    EXPECT_EQ(classic.non_manifold_edges, 0u);
    EXPECT_EQ(classic.inconsistent_edges, 0u);
    if (classic.boundary_edges > 0) ++seeds_with_holes;
  }
  EXPECT_GT(seeds_with_holes, 0u);
}

// ---- Ties: integer data, integral iso -------------------------------------------------------

TEST(MarchingCubes, IntegerDataWithIntegralIsoHasNoDegenerateTriangle) {
  for (unsigned seed = 0; seed < 40; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> level(0, 2);
    Volume volume({10, 10, 10}, {});
    for (float& v : volume.samples()) v = static_cast<float>(level(rng));  // a third equal iso
    for (const ExtractOptions& options : {kClosed, kOpen}) {
      const TriangleMesh mesh = extract_isosurface(volume, 1.0f, options);
      const MeshCheck check = check_mesh(mesh);
      SCOPED_TRACE(testing::Message() << "seed " << seed);
      EXPECT_EQ(check.degenerate_triangles, 0u);
      EXPECT_EQ(check.non_manifold_edges, 0u);
      EXPECT_EQ(check.non_manifold_vertices, 0u);
      EXPECT_EQ(check.inconsistent_edges, 0u);
      if (options.close_borders) {
        EXPECT_EQ(check.boundary_edges, 0u);
      }
    }
  }
}

TEST(MarchingCubes, SamplesEqualToIsoAreInsideAndVerticesStayOffThem) {
  // A 3×3×3 block equal to iso in a zero volume: inside, with its surface kEdgeMargin outside
  // the block's samples.
  Volume volume({7, 7, 7}, {});
  for (int k = 2; k <= 4; ++k) {
    for (int j = 2; j <= 4; ++j) {
      for (int i = 2; i <= 4; ++i) volume.at(i, j, k) = 100.0f;
    }
  }
  const TriangleMesh mesh = extract_isosurface(volume, 100.0f, kClosed);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_EQ(check.euler_characteristic, 2);
  for (const auto& p : mesh.positions) {
    float outside = 0.0f;  // how far the vertex lies outside the block [2, 4]³
    for (float x : p) outside = std::max({outside, 2.0f - x, x - 4.0f});
    EXPECT_NEAR(outside, kEdgeMargin, 1e-5);
  }
}

// ---- Analytic volumes -----------------------------------------------------------------------

TEST(MarchingCubes, SphereHasTheBallsVolumeAreaAndTopology) {
  const double r = 10.3;
  const Volume volume = sphere_volume(32, r, 15.5, 15.2, 15.7);
  const TriangleMesh mesh = extract_isosurface(volume, 0.0f, kClosed);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_EQ(check.components, 1u);
  EXPECT_EQ(check.euler_characteristic, 2);
  // Linear interpolation of R − |x| puts vertices almost on the sphere and the flat triangles
  // between them cut inside: measured −0.56 % volume and −0.30 % area at R = 10.3 (the errors
  // fall as 1/R², see SphereErrorIsSecondOrder). Tolerances: 0.8 % and 0.5 %.
  const double volume_exact = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double area_exact = 4.0 * std::numbers::pi * r * r;
  EXPECT_NEAR(check.volume / volume_exact, 1.0, 0.008);
  EXPECT_NEAR(check.area / area_exact, 1.0, 0.005);
  EXPECT_LT(check.volume, volume_exact);  // inscribed
  // Normals: radial, outward.
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto& p = mesh.positions[v];
    const double d[3] = {p[0] - 15.5, p[1] - 15.2, p[2] - 15.7};
    const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const auto& n = mesh.normals[v];
    EXPECT_GT((n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / length, 0.99);
  }
}

TEST(MarchingCubes, SphereErrorIsSecondOrder) {
  // Relative volume error × R² is about −0.6 for every radius (measured −0.59 … −0.60 for
  // R = 6.2, 10.3, 20.3): the extraction converges at second order in the voxel size.
  for (double r : {6.2, 10.3, 20.3}) {
    const std::int64_t n = static_cast<std::int64_t>(2 * r) + 8;
    const double c = 0.5 * static_cast<double>(n - 1);
    const Volume volume = sphere_volume(n, r, c + 0.13, c - 0.2, c + 0.07);
    const MeshCheck check = check_mesh(extract_isosurface(volume, 0.0f, kClosed));
    EXPECT_EQ(check.euler_characteristic, 2);
    const double relative = check.volume / (4.0 / 3.0 * std::numbers::pi * r * r * r) - 1.0;
    EXPECT_NEAR(relative * r * r, -0.6, 0.1) << "R = " << r;
  }
}

TEST(MarchingCubes, SphereHasNoAmbiguityAndClassicAgrees) {
  const Volume volume = sphere_volume(24, 8.4, 11.3, 11.6, 11.1);
  AmbiguityStats stats;
  ExtractOptions options = kClosed;
  options.stats = &stats;
  const TriangleMesh consistent = extract_isosurface(volume, 0.0f, options);
  const TriangleMesh classic = extract_isosurface(volume, 0.0f, kClassic);
  EXPECT_EQ(stats.cubes_with_ambiguous_faces[0], stats.boundary_cubes);
  EXPECT_EQ(consistent.positions, classic.positions);
  EXPECT_EQ(consistent.triangles, classic.triangles);
}

TEST(MarchingCubes, TorusHasEulerCharacteristicZero) {
  const double big = 10.0;
  const double small = 4.0;
  const Volume volume = sample_volume(32, 32, 14, [&](double x, double y, double z) {
    const double dx = x - 15.6;
    const double dy = y - 15.3;
    const double dz = z - 6.7;
    const double ring = std::sqrt(dx * dx + dy * dy) - big;
    return small - std::sqrt(ring * ring + dz * dz);
  });
  const MeshCheck check = check_mesh(extract_isosurface(volume, 0.0f, kClosed));
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_EQ(check.components, 1u);
  EXPECT_EQ(check.euler_characteristic, 0);
  const double volume_exact = 2.0 * std::numbers::pi * std::numbers::pi * big * small * small;
  const double area_exact = 4.0 * std::numbers::pi * std::numbers::pi * big * small;
  // Measured −1.30 % volume, −0.36 % area (the tube radius 4 voxels sets the error).
  EXPECT_NEAR(check.volume / volume_exact, 1.0, 0.016);
  EXPECT_NEAR(check.area / area_exact, 1.0, 0.006);
}

TEST(MarchingCubes, BoxHasExactVolumeAndArea) {
  // Samples +1 on a block of a×b×c samples, −1 elsewhere, iso 0: every vertex at an edge
  // midpoint. The surface is the block grown by ½ with every edge and corner chamfered:
  //   faces   on the inner box (a−1)(b−1)(c−1) grown by slabs ½ thick,
  //   edges   triangular prisms with legs ½ (cross-section ⅛), width √½,
  //   corners tetrahedra with legs ½ (volume 1/48), equilateral triangles of side √½.
  const int a = 5, b = 6, c = 4;
  Volume volume({10, 11, 9}, {});
  for (float& v : volume.samples()) v = -1.0f;
  for (int k = 3; k < 3 + c; ++k) {
    for (int j = 2; j < 2 + b; ++j) {
      for (int i = 2; i < 2 + a; ++i) volume.at(i, j, k) = 1.0f;
    }
  }
  const double x = a - 1, y = b - 1, z = c - 1;
  const double volume_exact =
      x * y * z + 0.5 * 2.0 * (x * y + y * z + z * x) + 4.0 * 0.125 * (x + y + z) + 8.0 / 48.0;
  const double area_exact =
      2.0 * (x * y + y * z + z * x) + 4.0 * std::sqrt(0.5) * (x + y + z) + std::sqrt(3.0);
  for (const ExtractOptions& options : {kClosed, kOpen, kClassic}) {
    const MeshCheck check = check_mesh(extract_isosurface(volume, 0.0f, options));
    EXPECT_TRUE(check.closed_manifold());
    EXPECT_EQ(check.euler_characteristic, 2);
    EXPECT_NEAR(check.volume, volume_exact, 1e-9);
    EXPECT_NEAR(check.area, area_exact, 1e-9);
  }
}

TEST(MarchingCubes, VolumeFillingBlobIsClosedAtTheBorder) {
  // Everything inside: the closed surface is the bounding box of the samples, kEdgeMargin out,
  // with chamfers of that size.
  Volume volume({6, 5, 4}, {});
  for (float& v : volume.samples()) v = 3.0f;
  const MeshCheck check = check_mesh(extract_isosurface(volume, 1.0f, kClosed));
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_EQ(check.euler_characteristic, 2);
  // (5+2δ)(4+2δ)(3+2δ) less the chamfers: 60 + 0.094 + O(δ²).
  EXPECT_NEAR(check.volume, 60.094, 1e-3);
}

// ---- Statistics, determinism, patient space --------------------------------------------------

TEST(MarchingCubes, StatisticsCountAmbiguousCubes) {
  // Case 13 (v0, v2, v5, v7 inside): all six faces ambiguous.
  Volume volume({2, 2, 2}, {});
  std::mt19937 rng(3);
  set_cube(volume, 0b10100101, 0, 0, 0, rng);
  AmbiguityStats stats;
  ExtractOptions options = kOpen;
  options.stats = &stats;
  extract_isosurface(volume, 0.0f, options);
  EXPECT_EQ(stats.boundary_cubes, 1u);
  EXPECT_EQ(stats.cubes_with_ambiguous_faces[6], 1u);

  const Volume noise = noise_volume(12, 12, 12, 7);
  options.close_borders = true;
  extract_isosurface(noise, 0.5f, options);
  std::size_t sum = 0;
  for (int k = 0; k < 7; ++k) sum += stats.cubes_with_ambiguous_faces[k];
  EXPECT_EQ(sum, stats.boundary_cubes);
  EXPECT_EQ(stats.cubes_with_ambiguous_faces[4], 0u);
  EXPECT_EQ(stats.cubes_with_ambiguous_faces[5], 0u);
  EXPECT_GT(stats.cubes_with_ambiguous_faces[1], 0u);
  EXPECT_GT(stats.joined_faces, 0u);
}

TEST(MarchingCubes, DeciderIsSymmetricInTheFacesOrientation) {
  // Both cubes of a face see it from opposite sides and may start on either inside corner.
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int trial = 0; trial < 1000; ++trial) {
    const float a = 0.5f + u(rng), c = 0.5f + u(rng), b = 0.5f - u(rng), d = 0.5f - u(rng);
    const bool joined = detail::face_joins_inside(a, b, c, d, 0.5f);
    EXPECT_EQ(detail::face_joins_inside(c, d, a, b, 0.5f), joined);
    EXPECT_EQ(detail::face_joins_inside(a, d, c, b, 0.5f), joined);
    EXPECT_EQ(detail::face_joins_inside(c, b, a, d, 0.5f), joined);
  }
  // Saddle exactly at iso counts as joined (the >= rule): a c = b d after shifting by iso.
  EXPECT_TRUE(detail::face_joins_inside(2.0f, -1.0f, 0.5f, -1.0f, 0.0f));
  EXPECT_FALSE(detail::face_joins_inside(2.0f, -1.0f, 0.25f, -1.0f, 0.0f));
}

TEST(MarchingCubes, ResultIsDeterministic) {
  const Volume volume = noise_volume(10, 10, 10, 11);
  const TriangleMesh first = extract_isosurface(volume, 0.5f, kClosed);
  const TriangleMesh second = extract_isosurface(volume, 0.5f, kClosed);
  EXPECT_EQ(first.positions, second.positions);
  EXPECT_EQ(first.normals, second.normals);
  EXPECT_EQ(first.triangles, second.triangles);
}

// The cube records and ambiguity statistics of two extractions are equal.
void expect_same_records(const std::vector<BoundaryCube>& cubes, const AmbiguityStats& stats,
                         const std::vector<BoundaryCube>& expected_cubes,
                         const AmbiguityStats& expected_stats) {
  ASSERT_EQ(cubes.size(), expected_cubes.size());
  for (std::size_t k = 0; k < cubes.size(); ++k) {
    EXPECT_EQ(cubes[k].x, expected_cubes[k].x);
    EXPECT_EQ(cubes[k].y, expected_cubes[k].y);
    EXPECT_EQ(cubes[k].z, expected_cubes[k].z);
    EXPECT_EQ(cubes[k].index, expected_cubes[k].index);
    EXPECT_EQ(cubes[k].loops, expected_cubes[k].loops);
    EXPECT_EQ(cubes[k].first_triangle, expected_cubes[k].first_triangle);
  }
  EXPECT_EQ(stats.boundary_cubes, expected_stats.boundary_cubes);
  EXPECT_EQ(stats.cubes_with_ambiguous_faces, expected_stats.cubes_with_ambiguous_faces);
  EXPECT_EQ(stats.joined_faces, expected_stats.joined_faces);
  EXPECT_EQ(stats.centroid_vertices, expected_stats.centroid_vertices);
}

// Threads: slabs of layers extracted independently and concatenated must give exactly the
// serial result — vertex order, triangles, normals, cube records and statistics — for any
// thread count (slab boundaries move with it), open or closed, consistent or classic.
void expect_same_for_any_thread_count(const Volume& volume, float iso, ExtractOptions options) {
  std::vector<BoundaryCube> serial_cubes;
  AmbiguityStats serial_stats;
  options.threads = 1;
  options.cubes = &serial_cubes;
  options.stats = &serial_stats;
  const TriangleMesh serial = extract_isosurface(volume, iso, options);
  ASSERT_FALSE(serial.empty());
  for (unsigned threads : {2u, 3u, 4u, 0u}) {
    SCOPED_TRACE(threads);
    std::vector<BoundaryCube> cubes;
    AmbiguityStats stats;
    options.threads = threads;
    options.cubes = &cubes;
    options.stats = &stats;
    const TriangleMesh mesh = extract_isosurface(volume, iso, options);
    EXPECT_EQ(mesh.positions, serial.positions);
    EXPECT_EQ(mesh.normals, serial.normals);
    EXPECT_EQ(mesh.triangles, serial.triangles);
    expect_same_records(cubes, stats, serial_cubes, serial_stats);
  }
}

TEST(MarchingCubes, ThreadsGiveTheSerialResultOnNoise) {
  const Volume volume = noise_volume(13, 11, 70, 5);  // 71 layers: up to 8 slabs
  expect_same_for_any_thread_count(volume, 0.5f, kClosed);
  expect_same_for_any_thread_count(volume, 0.5f, kOpen);
  expect_same_for_any_thread_count(volume, 0.5f, kClassic);
}

// Without vertex normals only the normals go: positions, triangles, cube records and
// statistics are those of the extraction with them, serial or on slabs.
TEST(MarchingCubes, WithoutVertexNormalsOnlyTheNormalsGo) {
  const Volume volume = noise_volume(13, 11, 70, 5);
  for (ExtractOptions options : {kClosed, kOpen, kClassic}) {
    for (unsigned threads : {1u, 3u}) {
      SCOPED_TRACE(testing::Message() << options.close_borders << " " << threads);
      options.threads = threads;
      std::vector<BoundaryCube> with_cubes, without_cubes;
      AmbiguityStats with_stats, without_stats;
      options.cubes = &with_cubes;
      options.stats = &with_stats;
      const TriangleMesh with = extract_isosurface(volume, 0.5f, options);
      options.vertex_normals = false;
      options.cubes = &without_cubes;
      options.stats = &without_stats;
      const TriangleMesh without = extract_isosurface(volume, 0.5f, options);
      options.vertex_normals = true;
      ASSERT_EQ(with.normals.size(), with.positions.size());
      EXPECT_TRUE(without.normals.empty());
      EXPECT_EQ(without.positions, with.positions);
      EXPECT_EQ(without.triangles, with.triangles);
      expect_same_records(without_cubes, without_stats, with_cubes, with_stats);
      // The centre vertices, whose normal is their loop's mean, are among them.
      if (options.mode == ExtractOptions::Mode::consistent) {
        EXPECT_GT(with_stats.centroid_vertices, 0u);
      }
    }
  }
}

// slices_done is said once, with every slice, after the last read: the callback wipes the
// samples (every one outside), and the surface, normals included (read from the samples), is
// still the one made from the whole volume, on one slab or several. A volume without a
// surface says it too.
TEST(MarchingCubes, SaysOnceWhenTheVolumeIsReadNoMore) {
  const Volume volume = sphere_volume(48, 19.3, 23.6, 23.2, 23.9);
  for (unsigned threads : {1u, 3u}) {
    SCOPED_TRACE(threads);
    ExtractOptions options = kClosed;
    options.threads = threads;
    const TriangleMesh kept = extract_isosurface(volume, 0.0f, options);
    Volume wiped = volume;
    int calls = 0;
    options.slices_done = [&](std::int64_t begin, std::int64_t end) {
      ++calls;
      EXPECT_EQ(begin, 0);
      EXPECT_EQ(end, wiped.size().nz);
      std::fill(wiped.samples().begin(), wiped.samples().end(), -1.0f);
    };
    const TriangleMesh mesh = extract_isosurface(wiped, 0.0f, options);
    EXPECT_EQ(calls, 1);
    EXPECT_GT(mesh.triangles.size(), 0u);
    EXPECT_EQ(mesh.triangles, kept.triangles);
    EXPECT_EQ(mesh.positions, kept.positions);
    EXPECT_EQ(mesh.normals, kept.normals);
    calls = 0;
    EXPECT_TRUE(extract_isosurface(wiped, 0.0f, options).triangles.empty());
    EXPECT_EQ(calls, 1);
  }
}

TEST(MarchingCubes, ThreadsGiveTheSerialResultOnASphere) {
  const Volume volume = sphere_volume(48, 19.3, 23.6, 23.2, 23.9);
  expect_same_for_any_thread_count(volume, 0.0f, kClosed);
  expect_same_for_any_thread_count(volume, 0.0f, kOpen);
}

TEST(MarchingCubes, ThreadsOnThinVolumes) {
  // Fewer layers than a slab, and a surface only in the last layers.
  expect_same_for_any_thread_count(noise_volume(9, 9, 3, 2), 0.5f, kClosed);
  const Volume top = sample_volume(8, 8, 40, [](double, double, double z) { return z - 35.5; });
  expect_same_for_any_thread_count(top, 0.0f, kOpen);
  expect_same_for_any_thread_count(top, 0.0f, kClosed);
}

TEST(MarchingCubes, MirroringPatientMapKeepsTheSphereOutward) {
  const Volume volume = sphere_volume(20, 6.2, 9.5, 9.3, 9.6);
  TriangleMesh mesh = extract_isosurface(volume, 0.0f, kClosed);
  const double index_volume = check_mesh(mesh).volume;
  IndexToPatient g;
  g.origin = {-100, 50, 20};
  g.axes = {{{0.8, 0, 0}, {0, -0.8, 0}, {0, 0.1, 2.5}}};  // y flipped, tilted slices
  ASSERT_LT(g.determinant(), 0.0);
  const Vec3 centre = g.apply(9.5, 9.3, 9.6);
  to_patient(mesh, g);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_NEAR(check.volume, index_volume * -g.determinant(), 1e-6 * check.volume);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto& p = mesh.positions[v];
    const auto& n = mesh.normals[v];
    EXPECT_GT(n[0] * (p[0] - centre[0]) + n[1] * (p[1] - centre[1]) + n[2] * (p[2] - centre[2]),
              0.0);
  }
}

}  // namespace
}  // namespace typemerge::core
