// Multi-part 3MF (issue 16 item 3), through the executable on sample_series: `convert --preset
// bone,skin -o x.3mf` holds one object per preset, named after it and in its colour, whose every
// vertex and triangle equals that preset's own STL within the 3MF's decimal precision; --center
// moves the objects together; `batch --format 3mf` writes the same package per study. Read back
// with lib3mf (tests/support/three_mf_reader.h), STL read here independently.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "app/cli_runner.h"
#include "support/three_mf_reader.h"

namespace {

namespace fs = std::filesystem;
using typemerge::test::fresh_dir;
using typemerge::test::read_3mf;
using typemerge::test::read_file_bytes;
using typemerge::test::ReadThreeMf;
using typemerge::test::ReadThreeMfObject;
using typemerge::test::run_cli;

const std::string kSample = std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series";

using Corner = std::array<float, 3>;

// A binary STL's facets, three corners each, in file order.
std::vector<std::array<Corner, 3>> read_binary_stl(const fs::path& file) {
  const std::string bytes = read_file_bytes(file);
  std::vector<std::array<Corner, 3>> facets;
  if (bytes.size() < 84) return facets;
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  if (bytes.size() != 84 + 50 * std::size_t(count)) return facets;
  facets.resize(count);
  for (std::size_t f = 0; f < count; ++f) {
    std::memcpy(facets[f].data(), bytes.data() + 84 + 50 * f + 12, 36);
  }
  return facets;
}

// The 3MF's decimal precision: lib3mf 1.8 writes six decimals, truncated rather than rounded
// and formatted in float arithmetic (-71.5625 becomes "-71.562496"), so a coordinate read back
// is within 1e-6 plus a unit in the last place of the float written (measured on sample_series:
// at most 1e-6 + 0.4 ulp), plus the rounding of reading it into a float.
double precision(float written) {
  const float magnitude = std::fabs(written);
  return 1e-6 + 2.0 * (double(std::nextafter(magnitude, INFINITY)) - double(magnitude));
}

bool same_within_precision(float written, float read) {
  return std::fabs(double(written) - double(read)) <= precision(written);
}

// How many coordinates of the object's triangles differ from the STL facets' corners, in
// order; an object whose triangles or vertices do not pair with the STL's is a failure.
std::size_t differing_coordinates(const ReadThreeMfObject& object, const fs::path& stl) {
  const auto facets = read_binary_stl(stl);
  EXPECT_FALSE(facets.empty()) << stl;
  EXPECT_EQ(object.triangles.size(), facets.size()) << object.name;
  if (object.triangles.size() != facets.size()) return facets.size() * 9;
  std::set<Corner> distinct;
  std::size_t differing = 0;
  for (std::size_t t = 0; t < facets.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const Corner& expected = facets[t][k];
      distinct.insert(expected);
      const std::uint32_t v = object.triangles[t][k];
      if (v >= object.vertices.size()) return facets.size() * 9;
      for (int c = 0; c < 3; ++c) {
        if (!same_within_precision(expected[c], object.vertices[v][c])) ++differing;
      }
    }
  }
  // Every vertex used, none twice: as many as the STL has distinct corners.
  EXPECT_EQ(object.vertices.size(), distinct.size()) << object.name;
  return differing;
}

// The outputs the tests share, made once by the first test that needs them.
struct Outputs {
  fs::path dir;
  ReadThreeMf package;          // bone,skin -o x.3mf
  ReadThreeMf centered;         // bone,skin --center -o c.3mf
  std::string package_bytes;
};

const Outputs& outputs() {
  static const Outputs made = [] {
    Outputs o;
    o.dir = fresh_dir("multipart_3mf");
    for (const std::string& command : {
             "convert " + kSample + " --preset bone,skin -o " + (o.dir / "x.3mf").string(),
             "convert " + kSample + " --preset bone,skin --center -o " + (o.dir / "c.3mf").string(),
             "convert " + kSample + " --preset bone -o " + (o.dir / "bone.stl").string(),
             "convert " + kSample + " --preset skin -o " + (o.dir / "skin.stl").string(),
         }) {
      const auto r = run_cli(command);
      EXPECT_EQ(r.exit_code, 0) << command << "\n" << r.out << r.err;
    }
    o.package = read_3mf(o.dir / "x.3mf");
    o.centered = read_3mf(o.dir / "c.3mf");
    o.package_bytes = read_file_bytes(o.dir / "x.3mf");
    return o;
  }();
  return made;
}

TEST(MultipartThreeMf, OneNamedColouredObjectPerPresetInMillimetres) {
  const ReadThreeMf& package = outputs().package;
  EXPECT_TRUE(package.millimetre);
  EXPECT_EQ(package.application.rfind("typemerge ", 0), 0u) << package.application;
  EXPECT_NE(package.application.find("SPACE=LPS"), std::string::npos) << package.application;
  EXPECT_EQ(package.build_items, 2u);
  ASSERT_EQ(package.objects.size(), 2u);
  EXPECT_EQ(package.objects[0].name, "bone");
  EXPECT_EQ(package.objects[1].name, "skin");
  // The colours of the preset table (README "Presets"): bone ivory, skin tan.
  EXPECT_EQ(package.objects[0].srgba, (std::array<std::uint8_t, 4>{0xE3, 0xDA, 0xC9, 0xFF}));
  EXPECT_EQ(package.objects[1].srgba, (std::array<std::uint8_t, 4>{0xD2, 0xB4, 0x8C, 0xFF}));
  EXPECT_EQ(package.objects[0].material_name, "bone");
  EXPECT_EQ(package.objects[1].material_name, "skin");
}

TEST(MultipartThreeMf, EveryVertexAndTriangleEqualsTheSinglePresetStl) {
  const Outputs& o = outputs();
  ASSERT_EQ(o.package.objects.size(), 2u);
  EXPECT_EQ(differing_coordinates(o.package.objects[0], o.dir / "bone.stl"), 0u);
  EXPECT_EQ(differing_coordinates(o.package.objects[1], o.dir / "skin.stl"), 0u);
}

TEST(MultipartThreeMf, TheComparisonSeesAnObjectOutOfPlace) {
  // The positive control: the centred bone has the bone STL's triangles, moved.
  const Outputs& o = outputs();
  ASSERT_EQ(o.centered.objects.size(), 2u);
  EXPECT_GT(differing_coordinates(o.centered.objects[0], o.dir / "bone.stl"), 1000u);
  EXPECT_FALSE(same_within_precision(1.0f, 1.000002f));
  EXPECT_TRUE(same_within_precision(-71.5625f, -71.562496f));  // lib3mf's own writing of it
}

TEST(MultipartThreeMf, CenterMovesEveryObjectByTheSameOffset) {
  const Outputs& o = outputs();
  ASSERT_EQ(o.centered.objects.size(), 2u);
  ASSERT_EQ(o.package.objects.size(), 2u);
  EXPECT_NE(o.centered.application.find("CENTERED"), std::string::npos);
  const Corner& a = o.package.objects[0].vertices.at(0);
  const Corner& b = o.centered.objects[0].vertices.at(0);
  const Corner offset = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  EXPECT_GT(std::fabs(offset[0]) + std::fabs(offset[1]) + std::fabs(offset[2]), 1.0f)
      << "sample_series is not centred, so --center must move it";
  std::array<double, 3> lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
  std::size_t moved_otherwise = 0;
  for (int obj = 0; obj < 2; ++obj) {
    const auto& before = o.package.objects[obj];
    const auto& after = o.centered.objects[obj];
    ASSERT_EQ(after.vertices.size(), before.vertices.size());
    EXPECT_EQ(after.triangles, before.triangles);
    for (std::size_t v = 0; v < after.vertices.size(); ++v) {
      for (int c = 0; c < 3; ++c) {
        // Three coordinates read back (each within its precision) and a float subtraction:
        // some 10 µm at most, far below the difference between two objects' own centring
        // (millimetres on sample_series).
        const float x = before.vertices[v][c], y = after.vertices[v][c];
        const double allowed = precision(x) + precision(y) + precision(a[c]) + precision(b[c]);
        if (std::fabs(double(y) - double(x) - double(offset[c])) > allowed) ++moved_otherwise;
        lo[c] = std::min(lo[c], double(after.vertices[v][c]));
        hi[c] = std::max(hi[c], double(after.vertices[v][c]));
      }
    }
  }
  EXPECT_EQ(moved_otherwise, 0u);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(lo[c] + hi[c], 0.0, 1e-4) << "axis " << c;
}

TEST(MultipartThreeMf, BatchWritesTheSamePackagePerStudy) {
  const Outputs& o = outputs();
  const fs::path root = fresh_dir("multipart_batch_root");
  fs::copy(kSample, root / "head", fs::copy_options::recursive);
  const fs::path out = fresh_dir("multipart_batch_out");
  const std::string batch = "batch " + root.string() + " --preset bone,skin --out " + out.string();
  const auto r = run_cli(batch + " --format 3mf");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(out / "head")) {
    files.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(files, std::vector<std::string>{"head.3mf"});
  // convert's options do not change with the batch (threads do not change outputs): same bytes.
  EXPECT_EQ(read_file_bytes(out / "head" / "head.3mf"), o.package_bytes);
  EXPECT_NE(read_file_bytes(out / "summary.csv").find("head/head.3mf"), std::string::npos);

  // Another format is another parameter: the study is converted again and the package goes.
  const auto stl = run_cli(batch);
  ASSERT_EQ(stl.exit_code, 0) << stl.out << stl.err;
  EXPECT_TRUE(fs::exists(out / "head" / "bone.stl"));
  EXPECT_TRUE(fs::exists(out / "head" / "skin.stl"));
  EXPECT_FALSE(fs::exists(out / "head" / "head.3mf"));
}

}  // namespace
