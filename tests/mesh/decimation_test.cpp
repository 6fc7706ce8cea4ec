// Tests of decimate_mesh: target counts, closed manifold results with the Euler
// characteristic of the input (sphere χ = 2, torus χ = 0), and the stated bound: every input
// vertex lies within max_error of the result.
#include "mesh/decimation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/mesh_checks.h"
#include "mesh/test_surfaces.h"

namespace typemerge::mesh {
namespace {

using P = std::array<double, 3>;

P sub(const P& a, const P& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const P& a, const P& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
P lerp2(const P& a, const P& ab, double s, const P& ac, double t) {
  return {a[0] + s * ab[0] + t * ac[0], a[1] + s * ab[1] + t * ac[1], a[2] + s * ab[2] + t * ac[2]};
}

// Squared distance from p to triangle abc (closest point by Voronoi regions, Ericson 2005).
double squared_distance(const P& p, const P& a, const P& b, const P& c) {
  const P ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  P q;
  if (d1 <= 0 && d2 <= 0) {
    q = a;
  } else {
    const P bp = sub(p, b);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    const P cp = sub(p, c);
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
    if (d3 >= 0 && d4 <= d3) {
      q = b;
    } else if (d6 >= 0 && d5 <= d6) {
      q = c;
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
      q = lerp2(a, ab, d1 / (d1 - d3), ac, 0.0);
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
      q = lerp2(a, ab, 0.0, ac, d2 / (d2 - d6));
    } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
      const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
      q = {b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])};
    } else {
      const double denom = 1.0 / (va + vb + vc);
      q = lerp2(a, ab, vb * denom, ac, vc * denom);
    }
  }
  const P d = sub(p, q);
  return dot(d, d);
}

P point(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

// max over the vertices of `from` of the distance to the surface `to` (one-sided Hausdorff
// on vertices). Triangles whose box is farther than `limit` are skipped, so a vertex with
// nothing within `limit` reports infinity.
double max_vertex_distance(const core::TriangleMesh& from, const core::TriangleMesh& to,
                           double limit) {
  std::vector<std::array<P, 2>> boxes;
  for (const auto& t : to.triangles) {
    std::array<P, 2> box{point(to.positions[t[0]]), point(to.positions[t[0]])};
    for (const auto v : t) {
      for (int k = 0; k < 3; ++k) {
        box[0][k] = std::min(box[0][k], double{to.positions[v][k]});
        box[1][k] = std::max(box[1][k], double{to.positions[v][k]});
      }
    }
    boxes.push_back(box);
  }
  double worst = 0.0;
  for (const auto& fp : from.positions) {
    const P p = point(fp);
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < to.triangles.size(); ++i) {
      bool near = true;
      for (int k = 0; k < 3 && near; ++k) {
        near = p[k] >= boxes[i][0][k] - limit && p[k] <= boxes[i][1][k] + limit;
      }
      if (!near) continue;
      const auto& t = to.triangles[i];
      best = std::min(best, squared_distance(p, point(to.positions[t[0]]),
                                             point(to.positions[t[1]]), point(to.positions[t[2]])));
    }
    worst = std::max(worst, std::sqrt(best));
  }
  return worst;
}

void expect_closed_with_euler(const DecimationReport& report, std::int64_t euler) {
  EXPECT_TRUE(report.validity.valid());
  for (const auto& line : report.validity.problems()) ADD_FAILURE() << line;
  EXPECT_EQ(report.validity.check.euler_characteristic, euler);
  EXPECT_EQ(report.validity.check.components, 1u);
}

TEST(Decimation, SphereReachesTheTargetClosedWithinTheBound) {
  const core::TriangleMesh original = test::sphere(48, {23.3, 23.6, 23.4, 18.0});
  core::TriangleMesh mesh = original;
  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 10;
  options.max_error = 0.25;

  const DecimationReport report = decimate_mesh(mesh, options);

  EXPECT_EQ(report.triangles_before, original.triangles.size());
  EXPECT_EQ(report.triangles_after, mesh.triangles.size());
  EXPECT_NEAR(static_cast<double>(mesh.triangles.size()),
              static_cast<double>(options.target_triangles), 0.01 * static_cast<double>(options.target_triangles));
  EXPECT_TRUE(report.reached_target);
  EXPECT_EQ(report.max_error, 0.25);
  EXPECT_TRUE(report.warnings.empty());
  expect_closed_with_euler(report, 2);
  EXPECT_LE(max_vertex_distance(original, mesh, 0.25), 0.25 + 1e-5);
  // Vertices stay on the sphere, so the coarser chords lose a little volume (≈ 1% here).
  const double volume = core::check_mesh(original).volume;
  EXPECT_NEAR(report.validity.check.volume, volume, 0.02 * volume);
}

TEST(Decimation, TorusKeepsItsHole) {
  const core::TriangleMesh original = test::torus(48, 14.0, 6.0);
  ASSERT_EQ(core::check_mesh(original).euler_characteristic, 0);
  core::TriangleMesh mesh = original;
  DecimationOptions options;
  options.target_triangles = original.triangles.size() / 8;
  options.max_error = 0.25;

  const DecimationReport report = decimate_mesh(mesh, options);

  EXPECT_NEAR(static_cast<double>(mesh.triangles.size()),
              static_cast<double>(options.target_triangles), 0.01 * static_cast<double>(options.target_triangles));
  expect_closed_with_euler(report, 0);
  EXPECT_LE(max_vertex_distance(original, mesh, 0.25), 0.25 + 1e-5);
}

TEST(Decimation, ErrorBoundAloneStopsWhereTheBoundSays) {
  const core::TriangleMesh original = test::sphere(40, {19.4, 19.7, 19.2, 15.0});
  core::TriangleMesh mesh = original;
  DecimationOptions options;  // no target: as far as max_error allows
  options.max_error = 0.05;

  const DecimationReport report = decimate_mesh(mesh, options);

  EXPECT_FALSE(report.reached_target);
  EXPECT_LT(report.triangles_after, report.triangles_before / 2);  // it did decimate
  expect_closed_with_euler(report, 2);
  EXPECT_LE(max_vertex_distance(original, mesh, 0.05), 0.05 + 1e-5);

  // A looser bound goes further.
  core::TriangleMesh looser = original;
  options.max_error = 0.2;
  EXPECT_LT(decimate_mesh(looser, options).triangles_after, report.triangles_after);
}

TEST(Decimation, NonManifoldInputIsLeftUnchangedWithAWarning) {
  // A book with three pages on the spine 0–1: OpenMesh cannot hold the third page.
  core::TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, -1, 0}};
  mesh.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const core::TriangleMesh original = mesh;
  DecimationOptions options;
  options.target_triangles = 1;
  const DecimationReport report = decimate_mesh(mesh, options);
  EXPECT_EQ(report.rejected_triangles, 1u);
  EXPECT_EQ(report.warnings.size(), 1u);
  EXPECT_EQ(mesh.triangles, original.triangles);
  EXPECT_EQ(report.triangles_after, 3u);
  EXPECT_FALSE(report.validity.valid());
}

TEST(Decimation, TouchingShellsAreSplitAndStayClosed) {
  core::TriangleMesh mesh = test::bowtie_tetrahedra();
  const DecimationReport report = decimate_mesh(mesh);
  EXPECT_EQ(report.split_vertices, 1u);
  EXPECT_EQ(report.triangles_after, 8u);  // a tetrahedron cannot lose a triangle
  EXPECT_TRUE(report.validity.valid());
  EXPECT_EQ(report.validity.check.components, 2u);
}

}  // namespace
}  // namespace typemerge::mesh
