// Surfaces for the mesh tests: analytic fields (inside where > 0) extracted by the core's
// marching cubes in voxel index space, which the tests read as millimetres (unit spacing).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/marching_cubes.h"
#include "core/mesh.h"
#include "core/test_volumes.h"

namespace typemerge::mesh::test {

struct Ball {
  double x, y, z, radius;
};

inline double distance(double x, double y, double z, const Ball& b) {
  return std::sqrt((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y) + (z - b.z) * (z - b.z));
}

// The union of balls in an n³ grid.
inline core::TriangleMesh balls(std::int64_t n, const std::vector<Ball>& list) {
  const core::Volume volume = core::test::sample_volume(n, n, n, [&](double x, double y, double z) {
    double field = -1e9;
    for (const Ball& b : list) field = std::max(field, b.radius - distance(x, y, z, b));
    return field;
  });
  return core::extract_isosurface(volume, 0.0f);
}

inline core::TriangleMesh sphere(std::int64_t n, const Ball& b) { return balls(n, {b}); }

// A spherical shell inner < r < outer about b's centre (b.radius unused), plus `islands`
// (solid balls, e.g. inside the cavity).
inline core::TriangleMesh hollow_shell(std::int64_t n, const Ball& centre, double outer,
                                       double inner, const std::vector<Ball>& islands = {}) {
  const core::Volume volume = core::test::sample_volume(n, n, n, [&](double x, double y, double z) {
    const double r = distance(x, y, z, centre);
    double field = std::min(outer - r, r - inner);
    for (const Ball& b : islands) field = std::max(field, b.radius - distance(x, y, z, b));
    return field;
  });
  return core::extract_isosurface(volume, 0.0f);
}

// Torus about the z axis through (c, c, c): major radius R, tube radius r.
inline core::TriangleMesh torus(std::int64_t n, double major, double minor) {
  const double c = 0.5 * static_cast<double>(n - 1);
  const core::Volume volume = core::test::sample_volume(n, n, n, [&](double x, double y, double z) {
    const double ring = std::hypot(x - c, y - c) - major;
    return minor - std::hypot(ring, z - c);
  });
  return core::extract_isosurface(volume, 0.0f);
}

// A ball whose field has uniform noise of ±amplitude added at every sample: a bumpy sphere
// (possibly with a few specks of debris near its surface).
inline core::TriangleMesh noisy_sphere(std::int64_t n, const Ball& b, double amplitude,
                                       unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-amplitude, amplitude);
  const core::Volume volume = core::test::sample_volume(
      n, n, n, [&](double x, double y, double z) { return b.radius - distance(x, y, z, b) + noise(rng); });
  return core::extract_isosurface(volume, 0.0f);
}

// Root mean square of |p − centre| − radius over the vertices.
inline double radial_rms(const core::TriangleMesh& mesh, const Ball& b) {
  double sum = 0.0;
  for (const auto& p : mesh.positions) {
    const double e = distance(p[0], p[1], p[2], b) - b.radius;
    sum += e * e;
  }
  return std::sqrt(sum / static_cast<double>(mesh.positions.size()));
}

//        3
//       /|\          unit right tetrahedron at the origin, faces wound outward
//      / | \         (the one of core's mesh_checks_test): V = 1/6
//     0--|--2
//      \ | /
//        1
inline core::TriangleMesh tetrahedron() {
  core::TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

// Two tetrahedra touching at vertex 0: the second is the first mirrored through the origin.
inline core::TriangleMesh bowtie_tetrahedra() {
  core::TriangleMesh m = tetrahedron();
  m.positions.push_back({-1, 0, 0});
  m.positions.push_back({0, -1, 0});
  m.positions.push_back({0, 0, -1});
  m.triangles.push_back({0, 4, 5});
  m.triangles.push_back({0, 6, 4});
  m.triangles.push_back({0, 5, 6});
  m.triangles.push_back({4, 6, 5});
  return m;
}

}  // namespace typemerge::mesh::test
