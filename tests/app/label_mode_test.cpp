// Label mode and NIfTI/NRRD inputs through the executable: label maps written by the test
// (support/volume_file_writers.h) from a synthetic scene — two touching balls, a one-voxel line,
// a single voxel, a small cube — as NIfTI, NRRD and a layered .seg.nrrd; every part checked
// for count, name, colour, validity (closed, manifold, oriented: core::check_mesh; crossings:
// CGAL through core::find_self_intersections), volume against its voxel volume, and the
// interpenetration of the touching balls. Then info, grey input and privacy.
#include "app/label_mode.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <utility>

#include "app/cli_runner.h"
#include "app/exit_codes.h"
#include "app/input_kind.h"
#include "app/label_census.h"
#include "app/label_names.h"
#include "app/volume_file_input.h"
#include "core/mesh_checks.h"
#include "core/mesh_distance.h"
#include "core/self_intersections.h"
#include "io/stl_writer.h"
#include "preprocess/denoise.h"
#include "support/test_data.h"
#include "support/three_mf_reader.h"
#include "support/volume_file_writers.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using test::run_cli;

constexpr int kN = 40;
const std::array<double, 3> kSpacing{0.9, 0.9, 1.2};

// The scene's labels, x fastest.
std::vector<double> scene() {
  std::vector<double> v(static_cast<std::size_t>(kN * kN * kN), 0.0);
  auto at = [&](int i, int j, int k) -> double& {
    return v[static_cast<std::size_t>(i + kN * (j + kN * k))];
  };
  for (int k = 0; k < kN; ++k) {
    for (int j = 0; j < kN; ++j) {
      for (int i = 0; i < kN; ++i) {
        const double d1 = std::hypot(i - 14.0, j - 20.0, k - 20.0);
        const double d2 = std::hypot(i - 26.0, j - 20.0, k - 20.0);
        if (d1 <= 8) {
          at(i, j, k) = 1;
        } else if (d2 <= 7) {
          at(i, j, k) = 2;  // touches label 1 where the balls meet
        }
      }
    }
  }
  for (int k = 5; k < 31; ++k) at(5, 5, k) = 3;  // a line one voxel thick
  at(35, 35, 35) = 4;                            // a single voxel
  for (int k = 3; k < 6; ++k)
    for (int j = 3; j < 6; ++j)
      for (int i = 32; i < 35; ++i) at(i, j, k) = 7;  // 27 voxels
  return v;
}

struct LabelFacts {
  std::size_t voxels = 0;
  std::size_t exposed_faces = 0;  // faces between the label and anything else
};

std::map<int, LabelFacts> facts(const std::vector<double>& v) {
  std::map<int, LabelFacts> out;
  auto label = [&](int i, int j, int k) {
    if (i < 0 || j < 0 || k < 0 || i >= kN || j >= kN || k >= kN) return 0;
    return int(v[static_cast<std::size_t>(i + kN * (j + kN * k))]);
  };
  for (int k = 0; k < kN; ++k)
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < kN; ++i) {
        const int l = label(i, j, k);
        if (l == 0) continue;
        ++out[l].voxels;
        const int n[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& d : n) out[l].exposed_faces += label(i + d[0], j + d[1], k + d[2]) != l;
      }
  return out;
}

test::NiftiSpec scene_nifti() {
  test::NiftiSpec spec;
  spec.dim = {3, kN, kN, kN, 1, 1, 1, 1};
  spec.datatype = test::kDtInt16;
  spec.values = scene();
  spec.srow = {{{kSpacing[0], 0, 0, -30}, {0, kSpacing[1], 0, 12}, {0, 0, kSpacing[2], 100}}};
  spec.intent_code = 1002;
  spec.descrip = "CanaryDescripQX 20110203";
  spec.aux_file = "CanaryAuxQX";
  spec.intent_name = "CanaryIntQX";
  spec.db_name = "CanaryDbQX";
  spec.extension = "CanaryExtensionQX";
  return spec;
}

core::TriangleMesh to_mesh(const test::ReadThreeMfObject& object) {
  core::TriangleMesh mesh;
  mesh.positions = object.vertices;
  mesh.triangles = object.triangles;
  return mesh;
}

// Ray parity along a direction no axis-aligned face is parallel to.
bool inside(const core::TriangleMesh& mesh, const std::array<double, 3>& p) {
  const std::array<double, 3> d{0.5773, 0.5774, 0.5775};
  int crossings = 0;
  for (const auto& t : mesh.triangles) {
    std::array<double, 3> a{}, b{}, c{};
    for (int x = 0; x < 3; ++x) {
      a[x] = mesh.positions[t[0]][x];
      b[x] = mesh.positions[t[1]][x];
      c[x] = mesh.positions[t[2]][x];
    }
    const std::array<double, 3> e1{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const std::array<double, 3> e2{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const std::array<double, 3> h{d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                                  d[0] * e2[1] - d[1] * e2[0]};
    const double det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
    if (std::abs(det) < 1e-12) continue;
    const std::array<double, 3> s{p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const double u = (s[0] * h[0] + s[1] * h[1] + s[2] * h[2]) / det;
    if (u < 0 || u > 1) continue;
    const std::array<double, 3> q{s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                                  s[0] * e1[1] - s[1] * e1[0]};
    const double w = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
    if (w < 0 || u + w > 1) continue;
    if ((e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det > 0) ++crossings;
  }
  return crossings % 2 == 1;
}

// How deep the surface of `a` (sampled densely) reaches inside the solid of `b`, in mm.
double penetration(const core::TriangleMesh& a, const core::TriangleMesh& b) {
  const core::TriangleMesh samples = core::surface_samples(a, 0.2);
  const auto& points = samples.positions;
  const std::vector<float> distance = core::point_to_mesh_distances(points, b, 10.0f);
  const core::BoundingBox box = core::bounding_box(b);
  auto in_box = [&](const std::array<float, 3>& p) {
    for (int c = 0; c < 3; ++c) {
      if (p[c] < box.min[c] || p[c] > box.max[c]) return false;
    }
    return true;
  };
  double depth = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!in_box(points[i])) continue;
    if (distance[i] > depth && inside(b, {points[i][0], points[i][1], points[i][2]}))
      depth = distance[i];
  }
  return depth;
}

void expect_valid(const core::TriangleMesh& mesh, const std::string& what) {
  const core::MeshCheck check = core::check_mesh(mesh);
  EXPECT_TRUE(check.closed_manifold()) << what;
  EXPECT_EQ(check.inconsistent_edges, 0u) << what;
  EXPECT_GT(check.volume, 0) << what << ": not wound outward";
  EXPECT_EQ(core::find_self_intersections(mesh).pairs.size(), 0u) << what;
}

// Volume tolerance: relative 6 % above 1,000 voxels; below, the surface lies within a voxel of
// the voxel boundary, so |V − n·v| < exposed faces × face area × spacing (its largest value).
void expect_volume(double volume_mm3, const LabelFacts& f, const std::string& what) {
  const double voxel = kSpacing[0] * kSpacing[1] * kSpacing[2];
  const double expected = double(f.voxels) * voxel;
  if (f.voxels > 1000) {
    EXPECT_NEAR(volume_mm3, expected, 0.06 * expected) << what;
  } else {
    const double face = kSpacing[0] * kSpacing[2];  // the largest face
    EXPECT_NEAR(volume_mm3, expected, double(f.exposed_faces) * face * 1.2 * 0.5) << what;
  }
  std::printf("  %s: %zu voxels, voxel volume %.1f mm3, surface %.1f mm3 (%+.1f %%)\n",
              what.c_str(), f.voxels, expected, volume_mm3, 100.0 * (volume_mm3 / expected - 1));
}

class LabelModeTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::fresh_dir("labels"); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(LabelModeTest, MultiLabelNiftiToNamedColouredValid3mf) {
  test::write_nifti(dir_ / "map.nii.gz", scene_nifti());
  {
    std::ofstream names(dir_ / "names.ctbl");
    names << "# 3D Slicer colour table\n0 Background 0 0 0 0\n1 liver 200 100 50 255\n"
             "2 spleen 10 20 250 255\n";
  }
  const auto run =
      run_cli("convert " + (dir_ / "map.nii.gz").string() + " --labels all -o " +
              (dir_ / "out.3mf").string() + " --label-names " + (dir_ / "names.ctbl").string() +
              " --report " + (dir_ / "report.json").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto package = test::read_3mf(dir_ / "out.3mf");
  ASSERT_EQ(package.objects.size(), 5u);
  const std::vector<std::string> names{"liver", "spleen", "label-3", "label-4", "label-7"};
  const auto truth = facts(scene());
  const int labels[] = {1, 2, 3, 4, 7};
  for (std::size_t o = 0; o < 5; ++o) {
    EXPECT_EQ(package.objects[o].name, names[o]);
    const core::TriangleMesh mesh = to_mesh(package.objects[o]);
    expect_valid(mesh, names[o]);
    expect_volume(core::check_mesh(mesh).volume, truth.at(labels[o]), names[o]);
  }
  EXPECT_EQ(package.objects[0].srgba[0], 200);
  EXPECT_EQ(package.objects[1].srgba[2], 250);
  EXPECT_EQ(package.objects[2].srgba[0], palette_colour(2)[0]);
  // The report: one entry a label.
  std::ifstream in(dir_ / "report.json");
  const auto report = nlohmann::json::parse(in);
  ASSERT_EQ(report["labels"].size(), 5u);
  EXPECT_EQ(report["labels"][3]["voxels"], 1);
  EXPECT_TRUE(report["labels"][2]["validity"]["closed_manifold"].get<bool>());
}

TEST_F(LabelModeTest, TouchingLabelsInterpenetrationBound) {
  test::write_nifti(dir_ / "map.nii", scene_nifti());
  // Bounds (label_mode.h): with mc, the surfaces of two labels meet but do not cross (0.001 mm
  // of float rounding); with tm, each merged polygon is within its ε = ½ voxel of mc's, so the
  // depth stays below half the largest spacing. Raw (σ = 0) and smoothed alike.
  for (const char* algorithm : {"mc", "tm"}) {
    for (const char* smoothing : {"", " --label-smoothing 0"}) {
      // Sanitizer builds run the default smoothing only (the ray tests are slow there).
      if (*smoothing != '\0' && !test::optimised_build()) continue;
      const auto run =
          run_cli("convert " + (dir_ / "map.nii").string() + " --labels 1,2 -o " +
                  (dir_ / "two.3mf").string() + " --algorithm " + algorithm + smoothing);
      ASSERT_EQ(run.exit_code, 0) << run.err;
      const auto package = test::read_3mf(dir_ / "two.3mf");
      ASSERT_EQ(package.objects.size(), 2u);
      const core::TriangleMesh a = to_mesh(package.objects[0]), b = to_mesh(package.objects[1]);
      const double depth = std::max(penetration(a, b), penetration(b, a));
      std::printf("  %s%s: interpenetration depth %.4f mm\n", algorithm, smoothing, depth);
      EXPECT_LE(depth, std::string(algorithm) == "mc" ? 0.001 : 0.5 * 1.2)
          << algorithm << smoothing;
    }
  }
}

TEST_F(LabelModeTest, NrrdLabelMapToStlFolderAndSlicerSegmentation) {
  const auto values = scene();
  const std::string geometry =
      "dimension: 3\nsizes: 40 40 40\nspace: right-anterior-superior\n"
      "space directions: (0.9,0,0) (0,0.9,0) (0,0,1.2)\nspace origin: (-30,12,100)\n";
  test::write_bytes(dir_ / "map.nrrd",
                    test::nrrd_bytes("type: uchar\n" + geometry +
                                         "encoding: gzip\ncontent: CanaryContentQX\n"
                                         "# CanaryCommentQX\nPatient:=CanaryKeyValueQX\n",
                                     test::raw_samples<std::uint8_t>(values), true),
                    false);
  auto run = run_cli("convert " + (dir_ / "map.nrrd").string() + " --labels 3,4 -o " +
                     (dir_ / "stl").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const char* name : {"label-3.stl", "label-4.stl"}) {
    ASSERT_TRUE(fs::exists(dir_ / "stl" / name)) << name;
    expect_valid(io::read_stl(dir_ / "stl" / name), name);
  }
  EXPECT_FALSE(fs::exists(dir_ / "stl" / "label-1.stl"));
  run = run_cli("convert " + (dir_ / "map.nrrd").string() + " --labels 1,2 --center --space ras " +
                "--check-intersections -o " + (dir_ / "centred").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("no crossing triangles"), std::string::npos) << run.err;
  {
    core::BoundingBox joint;
    for (const char* name : {"label-1.stl", "label-2.stl"}) {
      const core::BoundingBox box = core::bounding_box(io::read_stl(dir_ / "centred" / name));
      for (int c = 0; c < 3; ++c) {
        joint.min[c] = std::min(joint.min[c], box.min[c]);
        joint.max[c] = std::max(joint.max[c], box.max[c]);
      }
    }
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(joint.min[c] + joint.max[c], 0.0, 1e-3);
  }

  // A layered .seg.nrrd: layer 0 holds labels 1 and 2 (the balls), layer 1 the line as label 1,
  // overlapping nothing; names with characters unsafe in file names, and a repeated name.
  std::vector<double> layered;
  for (double v : values) {
    layered.push_back(v == 1 || v == 2 ? v : 0);
    layered.push_back(v == 3 ? 1 : 0);
  }
  test::write_bytes(
      dir_ / "s.seg.nrrd",
      test::nrrd_bytes("type: uchar\ndimension: 4\nsizes: 2 40 40 40\n"
                       "kinds: list domain domain domain\nspace: left-posterior-superior\n"
                       "space directions: none (0.9,0,0) (0,0.9,0) (0,0,1.2)\n"
                       "space origin: (0,0,0)\nencoding: gzip\n"
                       "Segment0_Name:=Left/Right ball\nSegment0_Color:=1 0 0\n"
                       "Segment0_LabelValue:=1\nSegment0_Layer:=0\n"
                       "Segment1_Name:=ball\nSegment1_Color:=0 1 0\n"
                       "Segment1_LabelValue:=2\nSegment1_Layer:=0\n"
                       "Segment2_Name:=ball\nSegment2_Color:=0 0 1\n"
                       "Segment2_LabelValue:=1\nSegment2_Layer:=1\n",
                       test::raw_samples<std::uint8_t>(layered), true),
      false);
  run = run_cli("convert " + (dir_ / "s.seg.nrrd").string() + " -o " + (dir_ / "seg").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const char* name : {"Left_Right_ball.stl", "ball.stl", "ball-2.stl"}) {
    ASSERT_TRUE(fs::exists(dir_ / "seg" / name)) << name;
    expect_valid(io::read_stl(dir_ / "seg" / name), name);
  }
  run = run_cli("convert " + (dir_ / "s.seg.nrrd").string() + " -o " + (dir_ / "seg.3mf").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto package = test::read_3mf(dir_ / "seg.3mf");
  ASSERT_EQ(package.objects.size(), 3u);
  EXPECT_EQ(package.objects[0].name, "Left/Right ball");
  EXPECT_EQ(package.objects[2].srgba[2], 255);
  EXPECT_EQ(package.objects[1].srgba[1], 255);
}

TEST_F(LabelModeTest, RefusalsAndInfo) {
  test::write_nifti(dir_ / "map.nii", scene_nifti());
  auto run = run_cli("convert " + (dir_ / "map.nii").string() + " --labels 9 -o " +
                     (dir_ / "x.3mf").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("label 9"), std::string::npos) << run.err;
  run = run_cli("convert " + (dir_ / "map.nii").string() + " --labels all --iso 1 -o " +
                (dir_ / "x.3mf").string());
  EXPECT_EQ(run.exit_code, 2);
  // A probability map is not a label map.
  test::NiftiSpec fuzzy = scene_nifti();
  fuzzy.datatype = test::kDtFloat32;
  fuzzy.values[100] = 0.25;
  test::write_nifti(dir_ / "fuzzy.nii", fuzzy);
  run = run_cli("convert " + (dir_ / "fuzzy.nii").string() + " --labels all -o " +
                (dir_ / "x.3mf").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("integer"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir_ / "x.3mf"));

  run = run_cli("info " + (dir_ / "map.nii").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("5 label(s)"), std::string::npos) << run.out;
  run = run_cli("info --json " + (dir_ / "map.nii").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto doc = nlohmann::json::parse(run.out);
  ASSERT_EQ(doc["labels"].size(), 5u);
  EXPECT_EQ(doc["labels"][3]["voxels"], 1);
  const auto box = doc["labels"][3]["bounding_box_lps_mm"];
  // Voxel (35,35,35) of RAS origin (-30,12,100): LPS x = 30 − 35·0.9 ± 0.45.
  EXPECT_NEAR(box[0][0].get<double>(), 30 - 35 * 0.9 - 0.45, 1e-3);
  EXPECT_NEAR(box[1][2].get<double>(), 100 + 35 * 1.2 + 0.6, 1e-3);
  EXPECT_NEAR(doc["labels"][3]["volume_ml"].get<double>(), 0.9 * 0.9 * 1.2 / 1000, 1e-9);
}

// Grey values given to label mode as "every label" (an MR's integers, no label intent) are
// refused at once, before any surface, with the way out named; the same map converts with its
// labels named, or when the file says it holds labels.
TEST_F(LabelModeTest, GreyValuesAreRefusedAsEveryLabelUnlessNamedOrDeclared) {
  test::NiftiSpec grey = scene_nifti();
  grey.intent_code = 0;
  std::fill(grey.values.begin(), grey.values.end(), 0.0);
  std::uint32_t state = 11;
  for (int k = 10; k < 22; ++k) {
    for (int j = 10; j < 22; ++j) {
      for (int i = 10; i < 22; ++i) {
        state = state * 1664525u + 1013904223u;
        // 120 grey levels in a 12-voxel cube
        grey.values[static_cast<std::size_t>(i + kN * (j + kN * k))] = 1 + (state >> 16) % 120;
      }
    }
  }
  test::write_nifti(dir_ / "grey.nii", grey);
  auto run = run_cli("convert " + (dir_ / "grey.nii").string() + " --labels all -o " +
                     (dir_ / "g.3mf").string());
  EXPECT_EQ(run.exit_code, kExitInputRefused);
  EXPECT_NE(run.err.find("does not look like labels: 120 values"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("--iso"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir_ / "g.3mf"));
  run = run_cli("convert " + (dir_ / "grey.nii").string() + " --labels 7,8 -o " +
                (dir_ / "named.3mf").string());
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir_ / "named.3mf"));
  grey.intent_code = 1002;  // NIFTI_INTENT_LABEL
  test::write_nifti(dir_ / "declared.nii", grey);
  run = run_cli("convert " + (dir_ / "declared.nii").string() + " --labels all -o " +
                (dir_ / "declared.3mf").string());
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_TRUE(fs::exists(dir_ / "declared.3mf"));
}

// label_coherence: the share of labelled voxels whose next voxel in the row has their label.
TEST(LabelCoherence, CountsEqualNeighboursAlongRows) {
  for (const bool int16 : {false, true}) {
    core::Volume layer({8, 2, 1}, core::IndexToPatient{});
    const float row[8] = {1, 1, 1, 1, 2, 2, 0, 3};  // the last voxel has no next: not counted
    for (int i = 0; i < 8; ++i) layer.at(i, 0, 0) = row[i];
    if (int16) {
      ASSERT_TRUE(layer.to_int16_if_exact());
    }
    EXPECT_DOUBLE_EQ(label_coherence(layer), 4.0 / 6.0) << int16;
  }
  EXPECT_EQ(label_coherence(core::Volume({3, 3, 3}, core::IndexToPatient{})), 1.0);
}

TEST_F(LabelModeTest, GreyNiftiConvertsWithIsoAndVolume) {
  test::NiftiSpec grey = scene_nifti();
  grey.datatype = test::kDtFloat32;
  grey.intent_code = 0;
  for (double& v : grey.values) v = v == 1 ? 300.0 : v == 2 ? 120.0 : 10.0;  // MR-like, not HU
  test::write_nifti(dir_ / "grey.nii.gz", grey);
  auto run = run_cli("convert " + (dir_ / "grey.nii.gz").string() + " --iso 200 -o " +
                     (dir_ / "grey.stl").string() + " --report " + (dir_ / "r.json").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  expect_valid(io::read_stl(dir_ / "grey.stl"), "iso 200");
  run = run_cli("convert " + (dir_ / "grey.nii.gz").string() +
                " --iso auto --denoise gaussian -o " + (dir_ / "auto.stl").string());
  EXPECT_EQ(run.exit_code, 0) << run.err;
  run = run_cli("convert " + (dir_ / "grey.nii.gz").string() + " --preset bone -o " +
                (dir_ / "bone.stl").string());
  EXPECT_EQ(run.exit_code, 1) << "a preset on values that are not HU";
  EXPECT_NE(run.err.find("Hounsfield"), std::string::npos) << run.err;
  run = run_cli("convert " + (dir_ / "grey.nii.gz").string() + " --iso 200 --max-memory 1M -o " +
                (dir_ / "m.stl").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("max-memory"), std::string::npos) << run.err;
  run = run_cli("volume " + (dir_ / "grey.nii.gz").string() + " --float -o " +
                (dir_ / "v.nrrd").string());
  EXPECT_EQ(run.exit_code, 0) << run.err;
}

TEST_F(LabelModeTest, NothingIdentifyingLeaves) {
  test::write_nifti(dir_ / "CanaryFileNameQX.nii.gz", scene_nifti());
  const auto values = scene();
  test::write_bytes(dir_ / "m.nrrd",
                    test::nrrd_bytes("type: uchar\ndimension: 3\nsizes: 40 40 40\n"
                                     "spacings: 1 1 1\nencoding: raw\ncontent: CanaryContentQX\n"
                                     "# CanaryCommentQX\nPatient:=CanaryKeyValueQX\n",
                                     test::raw_samples<std::uint8_t>(values), false),
                    false);
  std::string everything;
  for (const std::string& input :
       {(dir_ / "CanaryFileNameQX.nii.gz").string(), (dir_ / "m.nrrd").string()}) {
    for (const std::string& command :
         {"info " + input, "info --json " + input,
          "convert " + input + " --labels all -o " + (dir_ / "o.3mf").string() + " --report " +
              (dir_ / "o.json").string(),
          "convert " + input + " --labels 1,3 -o " + (dir_ / "o").string(),
          "convert " + input + " --iso 1 -o " + (dir_ / "g.stl").string() + " --report " +
              (dir_ / "g.json").string(),
          "volume " + input + " -o " + (dir_ / "v.nrrd").string()}) {
      const auto run = run_cli(command);
      EXPECT_EQ(run.exit_code, 0) << command << ": " << run.err;
      everything += run.out + run.err;
    }
  }
  for (const auto& entry : fs::recursive_directory_iterator(dir_)) {
    if (!entry.is_regular_file()) continue;
    const std::string name = entry.path().filename().string();
    if (name == "CanaryFileNameQX.nii.gz" || name == "m.nrrd") continue;
    everything += name + test::read_file_bytes(entry.path());
  }
  for (const char* canary :
       {"CanaryDescripQX", "20110203", "CanaryAuxQX", "CanaryIntQX", "CanaryDbQX",
        "CanaryExtensionQX", "CanaryContentQX", "CanaryCommentQX", "CanaryKeyValueQX"}) {
    EXPECT_EQ(everything.find(canary), std::string::npos) << canary;
  }
}

// Labels are made on several threads at once (label_surfaces.h): the files must not depend on
// how many.
TEST_F(LabelModeTest, SameBytesForAnyThreadCount) {
  test::write_nifti(dir_ / "map.nii.gz", scene_nifti());
  std::map<std::string, std::string> first;
  for (const char* threads : {"1", "2", "5"}) {
    const fs::path out = dir_ / (std::string("t") + threads);
    const auto run = run_cli("convert " + (dir_ / "map.nii.gz").string() + " --labels all -o " +
                             out.string() + " --threads " + threads);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::map<std::string, std::string> files;
    for (const auto& entry : fs::directory_iterator(out)) {
      files[entry.path().filename().string()] = test::read_file_bytes(entry.path());
    }
    EXPECT_GE(files.size(), 4u);
    if (first.empty()) first = files;
    EXPECT_TRUE(files == first) << threads << " threads";
  }
}

TEST(LabelModeRealData, SlicerLabelMapTwoLabels) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path map = data / "seg" / "dcmqi" / "liver_spine_seg.nrrd";
  if (!fs::exists(map)) GTEST_SKIP() << map << " absent";
  const fs::path dir = test::fresh_dir("labels_real");
  const auto run = run_cli("convert " + map.string() + " --labels all -o " +
                           (dir / "ls.3mf").string() + " --report " + (dir / "r.json").string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto package = test::read_3mf(dir / "ls.3mf");
  ASSERT_EQ(package.objects.size(), 2u);
  std::ifstream in(dir / "r.json");
  const auto report = nlohmann::json::parse(in);
  for (std::size_t o = 0; o < 2; ++o) {
    const core::TriangleMesh mesh = to_mesh(package.objects[o]);
    expect_valid(mesh, package.objects[o].name);
    const double voxel_ml = report["labels"][o]["voxel_volume_ml"].get<double>();
    EXPECT_NEAR(core::check_mesh(mesh).volume / 1000.0, voxel_ml, 0.06 * voxel_ml);
  }
  fs::remove_all(dir);
}

// The premise of the grey-value refusal on real files: Slicer's label maps have most labelled
// voxels beside their own label, a brain MR's grey values few; the MR with --labels all is
// refused at once (it made 254 surfaces in 30 s before).
TEST(LabelModeRealData, GreyMrRefusedAsEveryLabelAndLabelMapsCoherent) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path mr = data / "nifti" / "bet.nii.gz";
  if (!fs::exists(mr)) GTEST_SKIP() << mr << " absent";
  for (const char* name : {"liver_seg.nrrd", "heart_seg.nrrd", "liver_spine_seg.nrrd"}) {
    const fs::path map = data / "seg" / "dcmqi" / name;
    if (!fs::exists(map)) continue;
    const VolumeFile file = read_volume_file(map, input_kind(map));
    const double coherence = label_coherence(file.content.layers.front());
    std::printf("  %s: %.3f of labelled voxels beside their own label\n", name, coherence);
    EXPECT_GE(coherence, 0.8) << name;
  }
  const VolumeFile grey = read_volume_file(mr, input_kind(mr));
  const double coherence = label_coherence(grey.content.layers.front());
  std::printf("  bet.nii.gz: %.3f\n", coherence);
  EXPECT_LT(coherence, 0.1);
  const fs::path dir = test::fresh_dir("grey_labels_real");
  const auto run = run_cli("convert " + mr.string() + " --labels all -o " +
                           (dir / "bet.3mf").string());
  EXPECT_EQ(run.exit_code, kExitInputRefused);
  EXPECT_NE(run.err.find("does not look like labels: 254 values"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "bet.3mf"));
  fs::remove_all(dir);
}

// The check of the NIfTI geometry on a real series: the abdomen through dcm2niix
// (which flips the rows: a negative j axis) gives the DICOM folder's mc surface.
TEST(GreyRealData, Dcm2niixAbdomenGivesTheDicomSurface) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  if (!test::optimised_build()) GTEST_SKIP() << "two abdomen conversions: optimised build only";
  if (std::system("command -v dcm2niix >/dev/null 2>&1") != 0) GTEST_SKIP() << "no dcm2niix";
  const fs::path dir = test::fresh_dir("dcm2niix");
  const fs::path series = data / "ct" / "abdomen";
  ASSERT_EQ(std::system(("dcm2niix -z y -b n -f abdomen -o " + dir.string() + " " +
                         series.string() + " >/dev/null 2>&1")
                            .c_str()),
            0);
  for (const auto& [input, output] : {std::pair{series.string(), "dicom.stl"},
                                      std::pair{(dir / "abdomen.nii.gz").string(), "nifti.stl"}}) {
    const auto run = run_cli("convert " + input + " --iso 300 --algorithm mc --finish none -o " +
                             (dir / output).string());
    ASSERT_EQ(run.exit_code, 0) << run.err;
  }
  const core::TriangleMesh dicom = io::read_stl(dir / "dicom.stl");
  const core::TriangleMesh nifti = io::read_stl(dir / "nifti.stl");
  const auto distance = core::mesh_distance(dicom, nifti);
  std::printf(
      "  abdomen 300 HU, mc: DICOM %zu / NIfTI %zu triangles, Hausdorff (vertices) %.4f mm\n",
      dicom.triangles.size(), nifti.triangles.size(), distance.hausdorff());
  EXPECT_LE(distance.hausdorff(), 0.1);
  fs::remove_all(dir);
}

TEST(LabelNames, FormatsAndSafeStems) {
  const auto names = parse_label_names(
      "# comment\n0 Background 0 0 0 0\n1 Left-Cerebral-White-Matter 245 245 245 0\n"
      "  2   255    0    0        1  1  1    \"Left kidney\"\n3;liver\n4 aorta\n");
  ASSERT_EQ(names.size(), 4u);
  EXPECT_EQ(names.at(1).name, "Left-Cerebral-White-Matter");
  EXPECT_EQ(names.at(1).srgb, (std::array<std::uint8_t, 3>{245, 245, 245}));
  EXPECT_EQ(names.at(2).name, "Left kidney");
  EXPECT_EQ(names.at(2).srgb, (std::array<std::uint8_t, 3>{255, 0, 0}));
  EXPECT_EQ(names.at(3).name, "liver");
  EXPECT_FALSE(names.at(4).srgb.has_value());
  EXPECT_THROW(parse_label_names("x y\n"), CommandError);
  EXPECT_EQ(safe_unique_stems({"a/b", "A_b", "..", "", "x"}),
            (std::vector<std::string>{"a_b", "A_b-2", "label", "label-2", "x"}));
}

TEST(LabelField, ClampKeepsEveryVoxelsSide) {
  core::Volume layer({9, 9, 9}, {});
  layer.at(4, 4, 4) = 5;
  layer.at(1, 1, 1) = 5;
  LabelExtent extent{2, {1, 1, 1}, {4, 4, 4}};
  const core::Volume field = detail::label_field(layer, 5, extent, 0.5);
  // The padded box: 4 + 2 · (1 + ceil(1.5)) = 10 voxels a side, from index −2.
  EXPECT_EQ(field.size(), (core::VolumeSize{10, 10, 10}));
  // Voxel v of the layer is sample v + 2 of the field (the box starts at index 1 − 3).
  EXPECT_GT(field.at(6, 6, 6), detail::kLabelIso);
  EXPECT_GT(field.at(3, 3, 3), detail::kLabelIso);
  float outside_max = 0;
  for (std::int64_t k = 0; k < 10; ++k)
    for (std::int64_t j = 0; j < 10; ++j)
      for (std::int64_t i = 0; i < 10; ++i) {
        if ((i == 6 && j == 6 && k == 6) || (i == 3 && j == 3 && k == 3)) continue;
        outside_max = std::max(outside_max, field.at(i, j, k));
      }
  EXPECT_LT(outside_max, 0.5f);
}

// The field against its definition computed the plain way (label_mode.h): the indicator on the
// padded box, Gaussian, clamp; on labels whose boxes reach past every face of the layer.
TEST(LabelField, EqualsTheDefinitionAlsoAtTheLayersBorder) {
  core::IndexToPatient geometry;
  geometry.axes = {{{0.8, 0, 0}, {0, 0.9, 0}, {0, 0, 1.3}}};
  core::Volume layer({13, 11, 7}, geometry);
  std::uint32_t state = 7;
  for (float& v : layer.samples()) {
    state = state * 1664525u + 1013904223u;
    v = float((state >> 24) % 3);  // labels 0, 1, 2 scattered everywhere
  }
  const auto census = label_census(layer);
  for (double sigma : {0.0, 0.45, 1.1}) {
    for (const auto& [label, extent] : census) {
      const core::Volume field = detail::label_field(layer, label, extent, sigma);
      const auto pad = static_cast<std::int64_t>(1 + std::ceil(3.0 * sigma / 0.8));
      const auto& n = field.size();
      core::Volume indicator(n, field.geometry());
      for (std::int64_t k = 0; k < n.nz; ++k)
        for (std::int64_t j = 0; j < n.ny; ++j)
          for (std::int64_t i = 0; i < n.nx; ++i) {
            const std::int64_t x = i + extent.min[0] - pad, y = j + extent.min[1] - pad,
                               z = k + extent.min[2] - pad;
            const bool in = x >= 0 && y >= 0 && z >= 0 && x < 13 && y < 11 && z < 7 &&
                            layer.at(x, y, z) == float(label);
            indicator.at(i, j, k) = in ? 1.0f : 0.0f;
          }
      if (sigma == 0) {
        EXPECT_EQ(field.samples(), indicator.samples());
        continue;
      }
      preprocess::GaussianOptions gaussian;
      gaussian.sigma_mm = sigma;
      gaussian.truncate = 3.0;
      core::Samples expected = preprocess::gaussian_filter(indicator, gaussian).volume.samples();
      for (std::size_t v = 0; v < expected.size(); ++v) {
        expected[v] = indicator.samples()[v] > 0.5f ? std::max(expected[v], 0.5f + detail::kClampMargin)
                                                    : std::min(expected[v], 0.5f - detail::kClampMargin);
      }
      EXPECT_EQ(field.samples(), expected) << "label " << label << ", sigma " << sigma;
    }
  }
}

}  // namespace
}  // namespace typemerge::app
