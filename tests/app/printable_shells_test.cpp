// Issue 4's printability criterion, end to end: bone and skin from sample_series and from the
// abdomen CT come out as closed, manifold, outward shells — one shell where a single piece is
// asked for. Each STL is checked twice: by `typemerge stats`, and by an independent reading
// of the file here (vertices welded by their exact bytes, directed edges counted, shells by
// union-find over edges, signed volume per shell), which shares no code with the product.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <vector>

#include "app/cli_runner.h"
#include "support/test_data.h"

namespace {

namespace fs = std::filesystem;
using typemerge::test::fresh_dir;
using typemerge::test::read_file_bytes;
using typemerge::test::run_cli;

struct Shell {
  std::size_t triangles = 0;
  double volume_mm3 = 0;  // signed: > 0 outward (a solid), < 0 a cavity wall
};

struct StlShells {
  bool well_formed = false;      // size 84 + 50 n
  bool closed_oriented = false;  // every directed edge once, and its reverse once
  std::size_t degenerate = 0;    // triangles with a repeated vertex
  std::vector<Shell> shells;
  std::size_t outward() const {
    return static_cast<std::size_t>(std::count_if(shells.begin(), shells.end(),
                                                  [](const Shell& s) { return s.volume_mm3 > 0; }));
  }
  double volume() const {
    double sum = 0;
    for (const Shell& s : shells) sum += s.volume_mm3;
    return sum;
  }
};

StlShells read_shells(const fs::path& stl) {
  StlShells result;
  const std::string bytes = read_file_bytes(stl);
  if (bytes.size() < 84) return result;
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  if (bytes.size() != 84 + 50 * std::size_t{count}) return result;
  result.well_formed = true;

  // Weld corners by their exact bytes (STL repeats a shared vertex bit for bit): sort them.
  struct Corner {
    std::array<std::uint32_t, 3> bits;
    std::uint32_t slot;  // 3 × triangle + corner
  };
  std::vector<Corner> corners(3 * std::size_t{count});
  for (std::uint32_t slot = 0; slot < corners.size(); ++slot) {
    std::memcpy(corners[slot].bits.data(), bytes.data() + 84 + 50 * (slot / 3) + 12 + 12 * (slot % 3),
                12);
    corners[slot].slot = slot;
  }
  std::sort(corners.begin(), corners.end(),
            [](const Corner& a, const Corner& b) { return a.bits < b.bits; });
  std::vector<std::uint32_t> id(corners.size());
  std::vector<std::array<float, 3>> points;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    if (i == 0 || corners[i].bits != corners[i - 1].bits) {
      std::array<float, 3> p;
      std::memcpy(p.data(), corners[i].bits.data(), 12);
      points.push_back(p);
    }
    id[corners[i].slot] = static_cast<std::uint32_t>(points.size() - 1);
  }

  // Directed edges, sorted: closed and consistently oriented when each occurs once and so
  // does its reverse.
  std::vector<std::uint64_t> directed;
  directed.reserve(corners.size());
  std::vector<std::uint32_t> parent(points.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto root = [&](std::uint32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (std::uint32_t t = 0; t < count; ++t) {
    const std::uint32_t* v = id.data() + 3 * std::size_t{t};
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) ++result.degenerate;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = v[k], b = v[(k + 1) % 3];
      directed.push_back(std::uint64_t{a} << 32 | b);
      const std::uint32_t ra = root(a), rb = root(b);
      if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
    }
  }
  std::sort(directed.begin(), directed.end());
  result.closed_oriented = std::adjacent_find(directed.begin(), directed.end()) == directed.end();
  for (std::size_t i = 0; i < directed.size() && result.closed_oriented; ++i) {
    const std::uint64_t reverse = (directed[i] << 32) | (directed[i] >> 32);
    result.closed_oriented = std::binary_search(directed.begin(), directed.end(), reverse);
  }

  // Shells: signed volume per union-find root.
  std::vector<Shell> by_root(points.size());
  for (std::uint32_t t = 0; t < count; ++t) {
    const std::uint32_t* v = id.data() + 3 * std::size_t{t};
    Shell& shell = by_root[root(v[0])];
    ++shell.triangles;
    const auto& a = points[v[0]];
    const auto& b = points[v[1]];
    const auto& c = points[v[2]];
    shell.volume_mm3 += (double(a[0]) * (double(b[1]) * c[2] - double(b[2]) * c[1]) +
                         double(a[1]) * (double(b[2]) * c[0] - double(b[0]) * c[2]) +
                         double(a[2]) * (double(b[0]) * c[1] - double(b[1]) * c[0])) /
                        6.0;
  }
  for (const Shell& shell : by_root) {
    if (shell.triangles > 0) result.shells.push_back(shell);
  }
  return result;
}

nlohmann::json stats_of(const fs::path& stl) {
  const auto r = run_cli("stats --json " + stl.string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out);
}

// Checks a written file both ways; returns the independent reading.
StlShells check_written(const fs::path& stl) {
  const StlShells shells = read_shells(stl);
  EXPECT_TRUE(shells.well_formed) << stl;
  EXPECT_TRUE(shells.closed_oriented) << stl;
  EXPECT_EQ(shells.degenerate, 0u) << stl;
  const nlohmann::json stats = stats_of(stl);
  EXPECT_TRUE(stats["closed_manifold"].get<bool>()) << stl;
  EXPECT_EQ(stats["components"].get<std::size_t>(), shells.shells.size()) << stl;
  EXPECT_NEAR(stats["volume_mm3"].get<double>(), shells.volume(), 1e-6 * std::abs(shells.volume()));
  return shells;
}

StlShells convert_and_check(const std::string& input, const std::string& options,
                            const fs::path& stl) {
  const auto converted = run_cli("convert " + input + " " + options + " -o " + stl.string());
  EXPECT_EQ(converted.exit_code, 0) << converted.err;
  return check_written(stl);
}

const std::string kSample = std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series";

TEST(PrintableShells, SampleSkinIsOneShellAndTheSkullOneSolid) {
  const fs::path out = fresh_dir("shells_sample");
  const StlShells skin = convert_and_check(kSample, "--preset skin", out / "skin.stl");
  EXPECT_EQ(skin.shells.size(), 1u);
  EXPECT_GT(skin.volume(), 0.0);

  // Default bone: every piece of the phantom (skull, sinus walls, vertebra, styloid; the
  // ossicles are under the preset's 50 mm³) is its own closed solid.
  const StlShells bone = convert_and_check(kSample, "--preset bone", out / "bone.stl");
  EXPECT_GT(bone.outward(), 3u);

  // The largest solid is the skull with its cranial cavity: one outward shell and the cavity
  // wall inside it, holding the bone only (less than all bone, far less than the filled head).
  const StlShells skull = convert_and_check(kSample, "--preset bone --keep-largest",
                                            out / "skull.stl");
  EXPECT_EQ(skull.outward(), 1u);
  EXPECT_EQ(skull.shells.size(), 2u);
  EXPECT_LT(skull.volume(), bone.volume());
  EXPECT_GT(skull.volume(), 0.8 * bone.volume());

  // Filled, it is one shell: the solid head of bone a printed skull cap would be.
  const StlShells filled = convert_and_check(kSample, "--preset bone --keep-largest --fill-cavities",
                                             out / "filled.stl");
  EXPECT_EQ(filled.shells.size(), 1u);
  EXPECT_GT(filled.volume(), 2.0 * skull.volume());
}

TEST(PrintableShells, AbdomenBoneAndSkinAsSingleShells) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const std::string abdomen = (data / "ct" / "abdomen").string();
  const fs::path out = fresh_dir("shells_abdomen");
  const auto both = run_cli("convert " + abdomen + " --preset bone,skin -o " + out.string());
  ASSERT_EQ(both.exit_code, 0) << both.err;
  const StlShells skin = check_written(out / "skin.stl");
  EXPECT_EQ(skin.shells.size(), 1u);

  // The bones of the abdomen are separate solids (vertebrae, ribs, pelvis, femoral heads,
  // with cartilage below 226 HU between them); each is closed.
  const StlShells bones = check_written(out / "bone.stl");
  EXPECT_GT(bones.outward(), 10u);

  // The largest of them as one shell (cavities filled): what a print of one piece needs.
  const StlShells one = convert_and_check(abdomen, "--preset bone --keep-largest --fill-cavities",
                                          out / "one.stl");
  EXPECT_EQ(one.shells.size(), 1u);
  EXPECT_GT(one.volume(), 0.0);
  // Without filling, that solid keeps its marrow cavities: same outer shell, less volume.
  const StlShells hollow = convert_and_check(abdomen, "--preset bone --keep-largest",
                                             out / "hollow.stl");
  EXPECT_EQ(hollow.outward(), 1u);
  EXPECT_LT(hollow.volume(), one.volume());
}

}  // namespace
