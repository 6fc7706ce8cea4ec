// --reduce-to and --max-error through the executable: every row of the README's table of what
// they mean together (type merging within a bound in mm, to a count, the cap, refusals).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "app/cli_runner.h"
#include "ct_writer/ct_writer.h"
#include "support/test_data.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using typemerge::test::fresh_dir;

struct CommandRun {
  int exit_code = -1;
  std::string out;  // stdout and stderr
};

CommandRun run(const std::string& arguments) {
  const typemerge::test::CliRun r = typemerge::test::run_cli(arguments);
  return {r.exit_code, r.out + r.err};
}

// A 40 × 36 × 16 CT of 0.9 × 0.9 × 2.5 mm voxels: soft tissue (40 HU) in an ellipsoid body
// holding two bone-like lumps (700 HU) of wavy outline, in air.
const fs::path& body_series() {
  static const fs::path dir = [] {
    const fs::path d = fresh_dir("reduction_series");
    typemerge::ct_writer::SeriesLayout layout;
    layout.uid_seed = "reduction";
    layout.columns = 40;
    layout.rows = 36;
    layout.slices = 16;
    layout.pixel_spacing = {0.9, 0.9};
    layout.slice_spacing = 2.5;
    layout.hu = [](int i, int j, int k) {
      const double body = std::hypot((i - 19.5) / 17.0, (j - 17.5) / 15.0, (k - 7.5) / 9.0);
      const double wave = 1.5 * std::sin(0.7 * i) * std::cos(0.5 * j);
      const double a = std::hypot(i - 13.0, j - 15.0, (k - 7.0) * 2.5) + wave;
      const double b = std::hypot(i - 27.0, j - 20.0, (k - 8.0) * 2.5) - wave;
      if (a < 7.0 || b < 6.0) return 700.0;
      return body < 1.0 ? 40.0 : -1000.0;
    };
    const auto specs = typemerge::ct_writer::make_axial_series(layout);
    for (std::size_t k = 0; k < specs.size(); ++k) {
      typemerge::ct_writer::write_ct_slice(specs[k], d / ("s" + std::to_string(k)));
    }
    return d;
  }();
  return dir;
}

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

// convert with a report; returns the report's first surface (exit code checked).
json convert(const std::string& options, const std::string& name, int expected_exit = 0,
             std::string* out = nullptr) {
  const fs::path dir = fresh_dir("reduction_" + name);
  const CommandRun r = run("convert " + body_series().string() + " " + options + " -o " +
                           (dir / "out.stl").string() + " --report " +
                           (dir / "report.json").string());
  if (out != nullptr) *out = r.out;
  EXPECT_EQ(r.exit_code, expected_exit) << r.out;
  if (r.exit_code != 0) return nullptr;
  return read_json(dir / "report.json")["surfaces"][0];
}

std::size_t extracted_triangles(const json& surface) {
  return surface["steps"][0]["triangles"].get<std::size_t>();
}

// Batch's children ask for the report without the sampled distances (its summary does not
// use them): the surface is the same, the distance entry null.
TEST(Reduction, ReportWithoutDistancesLeavesOnlyTheDistancesOut) {
  const json with = convert("--iso 300", "with_distances");
  const json without = convert("--iso 300 --report-without-distances", "without_distances");
  ASSERT_FALSE(with.is_null());
  ASSERT_FALSE(without.is_null());
  EXPECT_GT(with["distance_to_marching_cubes"]["max_mm"].get<double>(), 0.0);
  EXPECT_TRUE(without["distance_to_marching_cubes"].is_null());
  EXPECT_EQ(without["triangles"], with["triangles"]);
  EXPECT_EQ(without["volume_ml"], with["volume_ml"]);
  EXPECT_EQ(without["validity"], with["validity"]);
}

TEST(Reduction, MaxErrorAloneIsTypeMergingAndCollapsesWithinThatBound) {
  const json plain = convert("--iso 300 --finish none", "plain");
  const json bounded = convert("--iso 300 --finish none --max-error 2", "bounded");
  ASSERT_FALSE(bounded.is_null());
  EXPECT_EQ(bounded["reduction"]["bound_mm"].get<double>(), 2.0);
  EXPECT_TRUE(bounded["reduction"]["target_met"].get<bool>());
  EXPECT_EQ(bounded["reduction"]["extractions"].get<int>(), 1);
  EXPECT_GT(bounded["reduction"]["collapses"].get<int>(), 0);  // the second stage ran
  EXPECT_EQ(bounded["reduction"]["triangles"].get<std::size_t>(), extracted_triangles(bounded));
  EXPECT_LE(bounded["distance_to_marching_cubes"]["max_mm"].get<double>(), 2.0 + 1e-3);
  EXPECT_GT(bounded["distance_to_marching_cubes"]["mean_mm"].get<double>(), 0.0);
  EXPECT_TRUE(bounded["validity"]["closed_manifold"].get<bool>());
  EXPECT_LT(extracted_triangles(bounded), extracted_triangles(plain));
  // Without the options the surface has no reduction entry, and its distance is still reported.
  EXPECT_TRUE(plain["reduction"].is_null());
  EXPECT_LE(plain["distance_to_marching_cubes"]["max_mm"].get<double>(), 0.5 * 2.5 + 1e-3);
}

TEST(Reduction, ReduceToAloneMeetsTheCountWithinOnePercent) {
  const json plain = convert("--iso 300 --finish none", "count_plain");
  const auto target = static_cast<std::size_t>(0.6 * double(extracted_triangles(plain)));
  const json reduced = convert("--iso 300 --finish none --reduce-to " + std::to_string(target),
                               "count");
  ASSERT_FALSE(reduced.is_null());
  const std::size_t n = extracted_triangles(reduced);
  EXPECT_LE(n, target);
  EXPECT_GE(double(n), 0.99 * double(target));
  EXPECT_TRUE(reduced["reduction"]["target_met"].get<bool>());
  EXPECT_EQ(reduced["reduction"]["target_triangles"].get<std::size_t>(), target);
  const double bound = reduced["reduction"]["bound_mm"].get<double>();
  EXPECT_LE(bound, reduced["reduction"]["cap_mm"].get<double>());
  EXPECT_DOUBLE_EQ(reduced["reduction"]["cap_mm"].get<double>(), 5 * 0.9);  // 5 finest steps
  EXPECT_LE(reduced["distance_to_marching_cubes"]["max_mm"].get<double>(), bound + 1e-3);
  EXPECT_TRUE(reduced["validity"]["closed_manifold"].get<bool>());
}

TEST(Reduction, BothGiveTheCountNeverBeyondTheBoundAndTheBoundWins) {
  std::string out;
  const json r = convert("--iso 300 --finish none --reduce-to 20 --max-error 0.8", "both", 0, &out);
  ASSERT_FALSE(r.is_null());
  EXPECT_FALSE(r["reduction"]["target_met"].get<bool>());
  EXPECT_EQ(r["reduction"]["bound_mm"].get<double>(), 0.8);
  EXPECT_EQ(r["reduction"]["cap_mm"].get<double>(), 0.8);
  EXPECT_GT(extracted_triangles(r), 20u);
  EXPECT_LE(r["distance_to_marching_cubes"]["max_mm"].get<double>(), 0.8 + 1e-3);
  // The count not reached: on the summary line, among the warnings, exit code 0.
  EXPECT_NE(out.find("--reduce-to NOT MET"), std::string::npos) << out;
  EXPECT_NE(out.find("warning: iso: --reduce-to 20 not met"), std::string::npos) << out;
  EXPECT_FALSE(r["warnings"].empty());
}

// Crossing pairs of a written STL, counted by `stats --self-intersections`.
int crossing_pairs(const fs::path& stl) {
  const CommandRun r = run("stats --json --self-intersections " + stl.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  const std::size_t brace = r.out.find('{');
  if (brace == std::string::npos) return -1;
  return json::parse(r.out.substr(brace))["self_intersecting_pairs"].get<int>();
}

// A count below what merging alone reaches within the cap: bounded collapses meet it, with
// every guarantee (the distance, closed manifold, marching cubes' topology, no crossing).
void expect_collapses_meet(const std::string& input, const std::string& options,
                           const std::string& name, double share) {
  const fs::path dir = fresh_dir("reduction_" + name);
  const CommandRun plain = run("convert " + input + " " + options + " --algorithm mc -o " +
                               (dir / "mc.stl").string() + " --report " +
                               (dir / "mc.json").string());
  ASSERT_EQ(plain.exit_code, 0) << plain.out;
  const json mc = read_json(dir / "mc.json")["surfaces"][0];
  const auto target = static_cast<std::size_t>(share * double(extracted_triangles(mc)));
  const CommandRun r = run("convert " + input + " " + options + " --reduce-to " +
                           std::to_string(target) + " -o " + (dir / "out.stl").string() +
                           " --report " + (dir / "out.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json reduced = read_json(dir / "out.json")["surfaces"][0];
  EXPECT_TRUE(reduced["reduction"]["target_met"].get<bool>()) << reduced["reduction"];
  EXPECT_GT(reduced["reduction"]["collapses"].get<std::size_t>(), 0u);
  const std::size_t n = extracted_triangles(reduced);
  EXPECT_LE(n, target);
  EXPECT_GE(double(n), 0.99 * double(target));
  const double bound = reduced["reduction"]["bound_mm"].get<double>();
  EXPECT_LE(bound, reduced["reduction"]["cap_mm"].get<double>());
  EXPECT_LE(reduced["distance_to_marching_cubes"]["max_mm"].get<double>(), bound + 1e-3);
  const json& valid = reduced["steps"][0]["validity"];
  EXPECT_TRUE(valid["closed_manifold"].get<bool>());
  EXPECT_EQ(valid["euler_characteristic"], mc["steps"][0]["validity"]["euler_characteristic"]);
  EXPECT_EQ(valid["components"], mc["steps"][0]["validity"]["components"]);
  EXPECT_EQ(crossing_pairs(dir / "out.stl"), 0);
}

TEST(Reduction, CountsBelowWhatMergingReachesAreMetByBoundedCollapses) {
  expect_collapses_meet(body_series().string(), "--iso 300 --finish none", "collapses", 0.1);
}

// The same on real CT: a small head (every build) and the abdomen at bone and skin (the
// optimised build: the 25 % and 10 % of marching cubes' triangles).
TEST(Reduction, RealCtCountsBelowWhatMergingReachesAreMet) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  expect_collapses_meet((data / "ct" / "head64_resampled").string(), "--iso 300 --finish none",
                        "head64", 0.1);
  if (!typemerge::test::optimised_build()) return;
  expect_collapses_meet((data / "ct" / "abdomen").string(), "--iso 300 --finish none",
                        "abdomen_bone", 0.25);
  expect_collapses_meet((data / "ct" / "abdomen").string(), "--iso -500 --finish none",
                        "abdomen_skin", 0.1);
}

// --max-memory's estimate (app/memory_budget.h) covers the collapses: at a small bound, where
// the merged surface they start from is largest, the conversion succeeds with its address
// space limited to the estimate (the optimised build: the limit is not applied under
// AddressSanitizer, and the collapses take minutes there).
TEST(Reduction, TheMemoryEstimateCoversTheCollapses) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  if (!typemerge::test::optimised_build()) GTEST_SKIP() << "the optimised build measures this";
  const std::string series = (data / "ct" / "abdomen").string();
  const fs::path dir = fresh_dir("reduction_memory");
  const std::string options = " --preset bone --max-error 0.5 --threads 2 -o " +
                              (dir / "bone.stl").string();
  const CommandRun refused = run("convert " + series + options + " --max-memory 1M");
  ASSERT_EQ(refused.exit_code, 1) << refused.out;
  const std::string says = "would need about ";
  const std::size_t at = refused.out.find(says);
  ASSERT_NE(at, std::string::npos) << refused.out;
  const long estimate_mib = std::stol(refused.out.substr(at + says.size()));
  const std::string budget = " --max-memory " + std::to_string(estimate_mib + 1) + "M";
  const CommandRun limited = run("convert " + series + options + budget);
  EXPECT_EQ(limited.exit_code, 0) << limited.out;
  EXPECT_TRUE(fs::exists(dir / "bone.stl"));
}

TEST(Reduction, EveryPresetSurfaceGetsTheCount) {
  const fs::path dir = fresh_dir("reduction_presets");
  const CommandRun r = run("convert " + body_series().string() +
                           " --preset bone,skin --min-component 1 --reduce-to 400 -o " +
                           dir.string() + " --report " + (dir / "report.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const json report = read_json(dir / "report.json");
  ASSERT_EQ(report["surfaces"].size(), 2u);
  for (const json& surface : report["surfaces"]) {
    EXPECT_EQ(surface["reduction"]["target_triangles"].get<std::size_t>(), 400u)
        << surface["name"];
    EXPECT_LE(surface["reduction"]["triangles"].get<std::size_t>(), 400u) << surface["name"];
  }
}

TEST(Reduction, MarchingCubesAlgorithmsRefuseThem) {
  for (const char* algorithm : {"mc", "classic"}) {
    for (const char* option : {"--max-error 1", "--reduce-to 100"}) {
      const CommandRun r = run("convert " + body_series().string() + " --iso 300 --algorithm " +
                               algorithm + " " + option + " -o " +
                               (fresh_dir("reduction_refused") / "x.stl").string());
      EXPECT_EQ(r.exit_code, 2) << r.out;
      EXPECT_NE(r.out.find("unreduced"), std::string::npos) << r.out;
    }
  }
}

TEST(Reduction, FinishNoneStillReduces) {
  const json none = convert("--preset bone --finish none --max-error 1.5", "finish_none");
  ASSERT_FALSE(none.is_null());
  EXPECT_EQ(none["steps"].size(), 1u);  // extraction only
  EXPECT_EQ(none["reduction"]["bound_mm"].get<double>(), 1.5);
  EXPECT_LE(none["distance_to_marching_cubes"]["max_mm"].get<double>(), 1.5 + 1e-3);
}

TEST(Reduction, SmoothingIsMeasuredAfterTheBound) {
  const json smoothed = convert("--iso 300 --max-error 1 --smooth 10", "smooth");
  ASSERT_FALSE(smoothed.is_null());
  const json& d = smoothed["distance_to_marching_cubes"];
  EXPECT_LE(d["max_mm"].get<double>(), 1.0 + 1e-3);  // before smoothing: the bound
  ASSERT_FALSE(d["finished_max_mm"].is_null());    // after: measured
  EXPECT_GT(d["finished_max_mm"].get<double>(), 0.0);
}

TEST(Reduction, HollowUsesTheReducedSurface) {
  const json hollow = convert("--preset skin --max-error 1 --hollow 3", "hollow");
  ASSERT_FALSE(hollow.is_null());
  EXPECT_TRUE(hollow["validity"]["closed_manifold"].get<bool>());
  EXPECT_FALSE(hollow["hollow"].is_null());
  EXPECT_EQ(hollow["reduction"]["bound_mm"].get<double>(), 1.0);
}

TEST(Reduction, DecimatorIsRemovedWithAMessageNamingTheReplacement) {
  const CommandRun r = run("convert " + body_series().string() +
                           " --iso 300 --reduce-to 100 --decimator meshopt -o " +
                           (fresh_dir("reduction_decimator") / "x.stl").string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--decimator was removed"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("type merging"), std::string::npos) << r.out;
}

// --merge-only: the merge within the bound, without the collapses (more triangles, the same
// bound); it needs --max-error and is refused with --reduce-to.
TEST(Reduction, MergeOnlyLeavesOutTheCollapses) {
  const json both = convert("--iso 300 --finish none --max-error 2", "merge_and_collapses");
  const json merged = convert("--iso 300 --finish none --max-error 2 --merge-only", "merge_only");
  ASSERT_FALSE(merged.is_null());
  ASSERT_FALSE(both.is_null());
  EXPECT_EQ(merged["reduction"]["collapses"].get<int>(), 0);
  EXPECT_EQ(merged["reduction"]["bound_mm"].get<double>(), 2.0);
  EXPECT_LE(merged["distance_to_marching_cubes"]["max_mm"].get<double>(), 2.0 + 1e-3);
  EXPECT_TRUE(merged["validity"]["closed_manifold"].get<bool>());
  EXPECT_EQ(extracted_triangles(merged),
            extracted_triangles(both) + 2 * both["reduction"]["collapses"].get<std::size_t>());
  for (const char* options : {"--merge-only", "--merge-only --max-error 1 --reduce-to 100"}) {
    const CommandRun r = run("convert " + body_series().string() + " --iso 300 " + options +
                             " -o " + (fresh_dir("reduction_merge_only") / "x.stl").string());
    EXPECT_EQ(r.exit_code, 2) << options << ": " << r.out;
    EXPECT_NE(r.out.find("--merge-only"), std::string::npos) << r.out;
  }
}

// --open-borders: the body (0 HU) is open where the volume cuts it; the collapses keep that
// border as it is (its vertices are never collapsed away) and every other guarantee.
TEST(Reduction, OpenBordersKeepTheirBorder) {
  const json open = convert("--iso 0 --finish none --open-borders --max-error 2 --merge-only",
                            "open_merged");
  ASSERT_FALSE(open.is_null());
  ASSERT_GT(open["validity"]["boundary_edges"].get<int>(), 0);  // the body meets the border
  for (const char* options : {"--max-error 2", "--reduce-to 200"}) {
    SCOPED_TRACE(options);
    const json r = convert(std::string("--iso 0 --finish none --open-borders ") + options,
                           "open_reduced");
    ASSERT_FALSE(r.is_null());
    EXPECT_GT(r["reduction"]["collapses"].get<int>(), 0);
    EXPECT_EQ(r["validity"]["boundary_edges"], open["validity"]["boundary_edges"]);
    EXPECT_EQ(r["validity"]["non_manifold_edges"].get<int>(), 0);
    EXPECT_EQ(r["validity"]["non_manifold_vertices"].get<int>(), 0);
    EXPECT_EQ(r["validity"]["euler_characteristic"], open["validity"]["euler_characteristic"]);
    EXPECT_LE(r["distance_to_marching_cubes"]["max_mm"].get<double>(),
              r["reduction"]["bound_mm"].get<double>() + 1e-3);
  }
}

TEST(Reduction, BadValuesAreRefused) {
  for (const char* option : {"--max-error 0", "--max-error -1", "--reduce-to 0", "--reduce-to x"}) {
    const CommandRun r = run("convert " + body_series().string() + " --iso 300 " + option +
                             " -o " + (fresh_dir("reduction_bad") / "x.stl").string());
    EXPECT_EQ(r.exit_code, 2) << option << ": " << r.out;
  }
}

}  // namespace
