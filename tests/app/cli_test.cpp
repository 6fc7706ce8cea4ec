// The typemerge executable as a user runs it: output, files written, exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "ct_writer/ct_writer.h"
#include "support/scratch_files.h"
#include "support/test_data.h"

namespace {

namespace fs = std::filesystem;

struct CommandRun {
  int exit_code = -1;
  std::string out;  // stdout and stderr together
};

CommandRun run(const std::string& arguments) {
  const std::string command = std::string(TYPEMERGE_EXE) + " " + arguments + " 2>&1";
  CommandRun result;
  FILE* pipe = popen(command.c_str(), "r");
  std::array<char, 4096> buffer{};
  while (std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    result.out.append(buffer.data(), n);
  }
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// Per process: two test runs on one machine (or ctest's parallel jobs) never share a folder.
fs::path fresh_dir(const std::string& name) {
  return typemerge::test::fresh_dir(name, "typemerge_cli_");
}

// A 20×16×10 series with a bright ball, written with patient data that must never show up.
fs::path write_ball_series(const std::string& name) {
  const fs::path dir = fresh_dir(name);
  typemerge::ct_writer::SeriesLayout layout;
  layout.uid_seed = name;
  layout.columns = 20;
  layout.rows = 16;
  layout.slices = 10;
  layout.pixel_spacing = {0.5, 0.6};
  layout.slice_spacing = 1.5;
  layout.origin = {-100, 50, 20};
  layout.hu = [](int i, int j, int k) {
    const double d = std::hypot(i - 10.0, j - 8.0, (k - 5.0) * 2);
    return d < 5 ? 1000.0 : -1000.0;
  };
  auto specs = typemerge::ct_writer::make_axial_series(layout);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    specs[k].patient_name = "Canary^Patientname";
    specs[k].patient_id = "CANARYID123";
    specs[k].patient_birth_date = "19421111";
    typemerge::ct_writer::write_ct_slice(specs[k], dir / ("f" + std::to_string(k)));
  }
  return dir;
}

// The sample series folder holds a README.md: listed as not DICOM, not as a damaged file.
TEST(Cli, InfoListsTextFilesAsNotDicom) {
  const CommandRun r = run("info " + std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("x not DICOM: not a DICOM file"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("README.md"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("unreadable DICOM"), std::string::npos) << r.out;
}

TEST(Cli, InfoJsonDescribesTheSeriesWithoutPatientData) {
  const fs::path dir = write_ball_series("info");
  const CommandRun r = run("info --json " + dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto document = nlohmann::json::parse(r.out);
  ASSERT_EQ(document["series"].size(), 1u);
  const auto& series = document["series"][0];
  EXPECT_EQ(series["size"], nlohmann::json({20, 16, 10}));
  EXPECT_NEAR(series["spacing_mm"][0].get<double>(), 0.6, 1e-9);
  EXPECT_NEAR(series["spacing_mm"][1].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(series["spacing_mm"][2].get<double>(), 1.5, 1e-9);
  EXPECT_EQ(series["hu_range"], nlohmann::json({-1000.0, 1000.0}));
  EXPECT_EQ(document["default_series"], series["id"]);
  for (const char* token : {"Canary", "CANARYID123", "19421111"}) {
    EXPECT_EQ(r.out.find(token), std::string::npos) << token;
  }
}

TEST(Cli, VolumeWritesNrrdWithLpsGeometry) {
  const fs::path dir = write_ball_series("volume");
  const fs::path out = fresh_dir("volume_out") / "ball.nrrd";
  const CommandRun r = run("volume " + dir.string() + " -o " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream in(out, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t header_end = text.find("\n\n");
  ASSERT_NE(header_end, std::string::npos);
  const std::string header = text.substr(0, header_end);
  EXPECT_NE(header.find("type: int16"), std::string::npos);
  EXPECT_NE(header.find("sizes: 20 16 10"), std::string::npos);
  EXPECT_NE(header.find("space: left-posterior-superior"), std::string::npos);
  EXPECT_NE(header.find("space directions: (0.59999999999999998,0,0) (0,0.5,0) (0,0,1.5)"),
            std::string::npos) << header;
  EXPECT_NE(header.find("space origin: (-100,50,20)"), std::string::npos) << header;
  EXPECT_EQ(text.size() - header_end - 2, std::size_t{20 * 16 * 10 * 2});
  // The centre voxel of the ball is bone, a corner is air.
  auto sample = [&](int i, int j, int k) {
    std::int16_t v = 0;
    std::memcpy(&v, text.data() + header_end + 2 + 2 * (i + 20 * (j + 16 * k)), 2);
    return v;
  };
  EXPECT_EQ(sample(10, 8, 5), 1000);
  EXPECT_EQ(sample(0, 0, 0), -1000);
  EXPECT_EQ(r.out.find("Canary"), std::string::npos);
}

TEST(Cli, ExitCodes) {
  EXPECT_EQ(run("").exit_code, 2);
  EXPECT_EQ(run("info").exit_code, 2);
  EXPECT_EQ(run("volume /nonexistent").exit_code, 2);  // -o is required
  const CommandRun missing = run("info /nonexistent/folder");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("no such file or folder"), std::string::npos) << missing.out;
  const fs::path empty = fresh_dir("empty");
  std::ofstream(empty / "readme.txt") << "not DICOM";
  const CommandRun nothing = run("volume " + empty.string() + " -o " + (empty / "v.nrrd").string());
  EXPECT_EQ(nothing.exit_code, 1);
  EXPECT_NE(nothing.out.find("no usable CT series"), std::string::npos) << nothing.out;
  EXPECT_FALSE(fs::exists(empty / "v.nrrd"));
  const fs::path dir = write_ball_series("exit");
  const CommandRun unknown = run("volume " + dir.string() + " --series s00000000 -o x.nrrd");
  EXPECT_EQ(unknown.exit_code, 1);
}

TEST(Cli, UnwritableOutputFailsWithoutLeavingAFile) {
  const fs::path dir = write_ball_series("unwritable");
  const CommandRun r = run("volume " + dir.string() + " -o /nonexistent_folder/v.nrrd");
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_FALSE(fs::exists("/nonexistent_folder"));
}

TEST(Cli, OutputIsReplacedAtomically) {
  // A leftover from an earlier run is replaced whole; no temporary file stays behind.
  const fs::path dir = write_ball_series("atomic");
  const fs::path out_dir = fresh_dir("atomic_out");
  std::ofstream(out_dir / "v.nrrd") << "old";
  ASSERT_EQ(run("volume " + dir.string() + " -o " + (out_dir / "v.nrrd").string()).exit_code, 0);
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(out_dir)) {
    ++files;
    EXPECT_EQ(entry.path().filename(), "v.nrrd");
  }
  EXPECT_EQ(files, 1u);
  EXPECT_GT(fs::file_size(out_dir / "v.nrrd"), 1000u);
}

TEST(Cli, InfoOnThePhantomStudyNamesWhatItSkipped) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const CommandRun r = run("info " + (data / "ct" / "phantom_study").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("localizer"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("secondary capture"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("DICOMDIR"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("512x512x28"), std::string::npos) << r.out;
}

}  // namespace

namespace {

// The abdomen lies on a foam pad wider than the body (−700 to −300 HU) over a carbon table.
// With the skin preset the surface is one closed shell of the body alone: no pad, no table
// (with --keep-table it spans the whole 55 cm field of view).
TEST(Cli, AbdomenSkinIsOneClosedShellWithoutTheTable) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const fs::path out = fresh_dir("abdomen_skin");
  const CommandRun converted = run("convert " + (data / "ct" / "abdomen").string() +
                                   " --preset bone,skin -o " + out.string());
  ASSERT_EQ(converted.exit_code, 0) << converted.out;
  for (const char* name : {"bone", "skin"}) {
    const CommandRun stats = run("stats --json " + (out / (std::string(name) + ".stl")).string());
    ASSERT_EQ(stats.exit_code, 0) << stats.out;
    const auto document = nlohmann::json::parse(stats.out);
    EXPECT_TRUE(document["closed_manifold"].get<bool>()) << name;
    if (std::string(name) == "skin") EXPECT_EQ(document["components"], 1);
  }
  // From the file itself: the width of the back, within 15 mm of the most posterior point
  // (+y in LPS), is the body's (about 29 cm), not the pad's (53 cm).
  const std::string bytes = [&] {
    std::ifstream in(out / "skin.stl", std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }();
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  ASSERT_EQ(bytes.size(), 84u + 50u * count);
  std::vector<std::array<float, 3>> points(std::size_t{count} * 3);
  float back = -1e9f;
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::memcpy(points[i].data(), bytes.data() + 84 + 50 * (i / 3) + 12 + 12 * (i % 3), 12);
    back = std::max(back, points[i][1]);
  }
  float lo = 1e9f, hi = -1e9f;
  for (const auto& p : points) {
    if (p[1] < back - 15.0f) continue;
    lo = std::min(lo, p[0]);
    hi = std::max(hi, p[0]);
  }
  EXPECT_LT(hi - lo, 350.0f);
  EXPECT_GT(hi - lo, 150.0f);
}

TEST(Cli, ConvertWritesAClosedSurfaceInPatientSpaceThatStatsConfirms) {
  const fs::path dir = write_ball_series("convert");
  const fs::path out = fresh_dir("convert_out") / "ball.stl";
  const CommandRun converted = run("convert " + dir.string() + " --iso 0 -o " + out.string());
  ASSERT_EQ(converted.exit_code, 0) << converted.out;
  const CommandRun stats = run("stats --json " + out.string());
  ASSERT_EQ(stats.exit_code, 0) << stats.out;
  const auto document = nlohmann::json::parse(stats.out);
  EXPECT_TRUE(document["closed_manifold"].get<bool>());
  EXPECT_EQ(document["components"], 1);
  EXPECT_EQ(document["euler_characteristic"], 2);
  // An ellipsoid of radii 5 columns (0.6 mm), 5 rows (0.5 mm), 2.5 slices (1.5 mm).
  const double expected = 4.0 / 3.0 * M_PI * 3.0 * 2.5 * 3.75;
  EXPECT_NEAR(document["volume_mm3"].get<double>(), expected, 0.3 * expected);

  // Every vertex lies where the ball is in LPS: columns 4..16 from x = −100 mm, rows 2..14
  // from y = 50 mm, slices 2..8 from z = 20 mm.
  std::ifstream in(out, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes.substr(0, 9), "typemerge");
  EXPECT_NE(bytes.substr(0, 80).find("SPACE=LPS"), std::string::npos);
  EXPECT_EQ(bytes.find("Canary"), std::string::npos);
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  for (std::uint32_t t = 0; t < count; ++t) {
    for (int corner = 0; corner < 3; ++corner) {
      float p[3];
      std::memcpy(p, bytes.data() + 84 + 50 * t + 12 + 12 * corner, 12);
      ASSERT_GT(p[0], -100 + 0.6 * 4);
      ASSERT_LT(p[0], -100 + 0.6 * 16);
      ASSERT_GT(p[1], 50 + 0.5 * 2);
      ASSERT_LT(p[1], 50 + 0.5 * 14);
      ASSERT_GT(p[2], 20 + 1.5 * 2);
      ASSERT_LT(p[2], 20 + 1.5 * 8);
    }
  }
}

TEST(Cli, ConvertRefusesAnIsoValueWithNoSurface) {
  const fs::path dir = write_ball_series("noiso");
  const fs::path out = fresh_dir("noiso_out") / "none.stl";
  const CommandRun r = run("convert " + dir.string() + " --iso 5000 -o " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no surface"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, StatsRefusesANonMesh) {
  const fs::path dir = fresh_dir("stats_bad");
  std::ofstream(dir / "x.stl") << "not a mesh";
  EXPECT_EQ(run("stats " + (dir / "x.stl").string()).exit_code, 1);
}

}  // namespace

namespace {

TEST(Cli, PresetsAreListed) {
  const CommandRun r = run("presets");
  ASSERT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("bone"), std::string::npos);
  EXPECT_NE(r.out.find("226"), std::string::npos);
  EXPECT_NE(r.out.find("skin"), std::string::npos);
  EXPECT_NE(r.out.find("-718"), std::string::npos);
}

TEST(Cli, PresetWindowAndPreview) {
  const fs::path dir = write_ball_series("preset");
  const fs::path out = fresh_dir("preset_out");
  const CommandRun bone = run("convert " + dir.string() + " --preset bone -o " +
                              (out / "bone.stl").string() + " --preview");
  ASSERT_EQ(bone.exit_code, 0) << bone.out;
  std::ifstream png(out / "bone.png", std::ios::binary);
  std::string signature(8, '\0');
  png.read(signature.data(), 8);
  EXPECT_EQ(signature, "\x89PNG\r\n\x1a\n");
  EXPECT_GT(fs::file_size(out / "bone.png"), 1000u);
  // The ball (1000 HU) lies inside the window 500..1500; nothing lies inside teeth's window.
  EXPECT_EQ(run("convert " + dir.string() + " --window 500,1500 -o " + (out / "w.stl").string())
                .exit_code, 0);
  const CommandRun teeth = run("convert " + dir.string() + " --preset teeth -o " +
                               (out / "teeth.stl").string());
  EXPECT_EQ(teeth.exit_code, 1);
  EXPECT_NE(teeth.out.find("absent"), std::string::npos) << teeth.out;
  EXPECT_FALSE(fs::exists(out / "teeth.stl"));
  EXPECT_EQ(run("convert " + dir.string() + " --preset bone --iso 3 -o x.stl").exit_code, 2);
  EXPECT_EQ(run("convert " + dir.string() + " --preset nonsense -o x.stl").exit_code, 2);
  EXPECT_EQ(run("convert " + dir.string() + " -o x.stl").exit_code, 2);
}

TEST(Cli, PresetRefusesDataThatIsNotHounsfield) {
  const fs::path dir = fresh_dir("not_hu");
  typemerge::ct_writer::SeriesLayout layout;
  layout.uid_seed = "not_hu";
  layout.rescale_intercept = 0;
  layout.hu = [](int i, int, int) { return i < 8 ? 0.0 : 2000.0; };  // air stored as 0
  for (const auto& spec : typemerge::ct_writer::make_axial_series(layout)) {
    typemerge::ct_writer::write_ct_slice(spec, dir / (spec.instance_number + ".dcm"));
  }
  const CommandRun r = run("convert " + dir.string() + " --preset bone -o " +
                           (fresh_dir("not_hu_out") / "b.stl").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("Hounsfield"), std::string::npos) << r.out;
}

}  // namespace

namespace {

TEST(Cli, SeveralPresetsInOneRunWithReport) {
  const fs::path dir = write_ball_series("multi");
  const fs::path out = fresh_dir("multi_out");
  // The ball is small (about 120 mm3): keep it through the presets' debris removal.
  const CommandRun r = run("convert " + dir.string() + " --preset bone,skin -o " + out.string() +
                           " --min-component 10 --report " + (out / "report.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(fs::exists(out / "bone.stl"));
  EXPECT_TRUE(fs::exists(out / "skin.stl"));
  std::ifstream in(out / "report.json");
  const auto report = nlohmann::json::parse(in);
  ASSERT_EQ(report["surfaces"].size(), 2u);
  for (const auto& surface : report["surfaces"]) {
    EXPECT_TRUE(surface["validity"]["closed_manifold"].get<bool>()) << surface["name"];
    EXPECT_GT(surface["volume_ml"].get<double>(), 0.0);
    EXPECT_GE(surface["steps"].size(), 1u);
  }
  EXPECT_EQ(report["input"]["size"], nlohmann::json({20, 16, 10}));
  EXPECT_EQ(report.dump().find("Canary"), std::string::npos);
  EXPECT_EQ(report.dump().find("CANARYID123"), std::string::npos);
  EXPECT_EQ(report["surfaces"][0]["name"], "bone");  // in the order asked, though made concurrently

  // Surfaces made together are the surfaces made alone, byte for byte.
  for (const char* name : {"bone", "skin"}) {
    const fs::path alone = out / (std::string(name) + "_alone.stl");
    ASSERT_EQ(run("convert " + dir.string() + " --preset " + name + " --min-component 10 -o " +
                  alone.string()).exit_code, 0);
    const auto bytes = [](const fs::path& f) {
      std::ifstream file(f, std::ios::binary);
      return std::string((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    };
    EXPECT_EQ(bytes(alone), bytes(out / (std::string(name) + ".stl"))) << name;
  }
}

TEST(Cli, TypeMergingHalvesTrianglesAndStaysClosed) {
  const fs::path dir = write_ball_series("tm");
  const fs::path out = fresh_dir("tm_out");
  ASSERT_EQ(run("convert " + dir.string() + " --iso 0 --algorithm mc --finish none -o " +
                (out / "mc.stl").string()).exit_code, 0);
  ASSERT_EQ(run("convert " + dir.string() + " --iso 0 --algorithm tm --finish none -o " +
                (out / "tm.stl").string()).exit_code, 0);
  const auto mc = nlohmann::json::parse(run("stats --json " + (out / "mc.stl").string()).out);
  const auto tm = nlohmann::json::parse(run("stats --json " + (out / "tm.stl").string()).out);
  EXPECT_TRUE(tm["closed_manifold"].get<bool>());
  EXPECT_EQ(tm["euler_characteristic"], mc["euler_characteristic"]);
  EXPECT_LT(tm["triangles"].get<double>(), 0.8 * mc["triangles"].get<double>());
  EXPECT_NEAR(tm["volume_mm3"].get<double>(), mc["volume_mm3"].get<double>(),
              0.05 * mc["volume_mm3"].get<double>());
}

}  // namespace

namespace {

TEST(Cli, FormatsAndSpaces) {
  const fs::path dir = write_ball_series("formats");
  const fs::path out = fresh_dir("formats_out");
  const std::string base = "convert " + dir.string() + " --iso 0 -o ";
  ASSERT_EQ(run(base + (out / "b.ply").string()).exit_code, 0);
  ASSERT_EQ(run(base + (out / "b.obj").string()).exit_code, 0);
  ASSERT_EQ(run(base + (out / "lps.stl").string() + " --ascii").exit_code, 0);
  ASSERT_EQ(run(base + (out / "ras.stl").string() + " --ascii --space ras").exit_code, 0);
  EXPECT_EQ(run(base + (out / "b.vtk").string()).exit_code, 2);
  auto text = [](const fs::path& file) {
    std::ifstream in(file);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(text(out / "b.ply").rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(text(out / "b.obj").find("\nf "), std::string::npos);
  // ASCII STL in RAS is the LPS one with x and y negated, and still closed and outward.
  const auto lps = nlohmann::json::parse(run("stats --json " + (out / "lps.stl").string()).out);
  const auto ras = nlohmann::json::parse(run("stats --json " + (out / "ras.stl").string()).out);
  EXPECT_TRUE(ras["closed_manifold"].get<bool>());
  EXPECT_NEAR(ras["volume_mm3"].get<double>(), lps["volume_mm3"].get<double>(), 1e-3);
  EXPECT_GT(ras["volume_mm3"].get<double>(), 0.0);
  const std::string ras_text = text(out / "ras.stl");
  const std::size_t at = ras_text.find("vertex ");
  float x = 0, y = 0, z = 0;
  ASSERT_EQ(std::sscanf(ras_text.c_str() + at, "vertex %f %f %f", &x, &y, &z), 3);
  EXPECT_GT(x, 100 - 0.6 * 16);  // the ball sits near x = −97 LPS, so near +97 RAS
  EXPECT_LT(y, -50 - 0.5 * 2);
}

}  // namespace

namespace {

// The surface lines up with the volume in LPS: every vertex of the STL, mapped into the NRRD's
// index space with the NRRD's own origin and directions, lies where the (trilinearly
// interpolated) HU volume crosses the iso value.
TEST(Cli, SurfaceLinesUpWithTheNrrdVolume) {
  const fs::path dir = write_ball_series("align");
  const fs::path out = fresh_dir("align_out");
  ASSERT_EQ(run("volume " + dir.string() + " --float -o " + (out / "v.nrrd").string()).exit_code, 0);
  ASSERT_EQ(run("convert " + dir.string() + " --iso 0 --finish none -o " +
                (out / "s.stl").string()).exit_code, 0);
  std::ifstream nrrd_in(out / "v.nrrd", std::ios::binary);
  const std::string nrrd((std::istreambuf_iterator<char>(nrrd_in)), std::istreambuf_iterator<char>());
  const std::size_t end = nrrd.find("\n\n");
  double origin[3], axes[3][3];
  const std::size_t at_origin = nrrd.find("space origin: ");
  ASSERT_EQ(std::sscanf(nrrd.c_str() + at_origin, "space origin: (%lf,%lf,%lf)", &origin[0],
                        &origin[1], &origin[2]), 3);
  const std::size_t at_axes = nrrd.find("space directions: ");
  ASSERT_EQ(std::sscanf(nrrd.c_str() + at_axes,
                        "space directions: (%lf,%lf,%lf) (%lf,%lf,%lf) (%lf,%lf,%lf)",
                        &axes[0][0], &axes[0][1], &axes[0][2], &axes[1][0], &axes[1][1],
                        &axes[1][2], &axes[2][0], &axes[2][1], &axes[2][2]), 9);
  const int nx = 20, ny = 16, nz = 10;
  auto sample = [&](int i, int j, int k) {
    float v = 0;
    std::memcpy(&v, nrrd.data() + end + 2 + 4 * (i + nx * (j + ny * k)), 4);
    return double(v);
  };
  std::ifstream stl_in(out / "s.stl", std::ios::binary);
  const std::string stl((std::istreambuf_iterator<char>(stl_in)), std::istreambuf_iterator<char>());
  std::uint32_t count = 0;
  std::memcpy(&count, stl.data() + 80, 4);
  ASSERT_GT(count, 100u);
  double worst = 0;
  for (std::uint32_t t = 0; t < count; ++t) {
    float p[3];
    std::memcpy(p, stl.data() + 84 + 50 * t + 12, 12);
    // The axes are diagonal for this axial series: index = (p − origin) / spacing.
    const double fi = (p[0] - origin[0]) / axes[0][0], fj = (p[1] - origin[1]) / axes[1][1],
                 fk = (p[2] - origin[2]) / axes[2][2];
    const int i = std::min(int(fi), nx - 2), j = std::min(int(fj), ny - 2), k = std::min(int(fk), nz - 2);
    const double u = fi - i, v = fj - j, w = fk - k;
    double value = 0;
    for (int c = 0; c < 8; ++c) {
      const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
      value += (di ? u : 1 - u) * (dj ? v : 1 - v) * (dk ? w : 1 - w) * sample(i + di, j + dj, k + dk);
    }
    worst = std::max(worst, std::abs(value));
  }
  // 2000 HU across a voxel: 0.1% of an edge (the tie margin) plus float rounding is a few HU.
  EXPECT_LT(worst, 10.0);
}

}  // namespace

namespace {

// Kills convert at 50 moments spread over a whole run; under its final name there is then either
// nothing or a complete, valid surface — never a truncated file.
TEST(Cli, KilledRunsLeaveNoPartialOutput) {
  const fs::path out = fresh_dir("kill_out");
  const fs::path stl = out / "bone.stl";
  // A killed run leaves its temporary file (nothing runs after SIGKILL); the next run that
  // writes the same output removes it, so there is never more than one.
  auto left_over = [&] {
    int count = 0;
    for (const auto& entry : fs::directory_iterator(out)) {
      const std::string name = entry.path().filename().string();
      count += name.rfind(".bone.stl.", 0) == 0 && name.ends_with(".partial");
    }
    return count;
  };
  const std::string sample = std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series";
  auto start = [&] {
    const pid_t pid = fork();
    if (pid == 0) {
      const int null = ::open("/dev/null", O_WRONLY);
      dup2(null, 1);
      dup2(null, 2);
      execl(TYPEMERGE_EXE, TYPEMERGE_EXE, "convert", sample.c_str(), "--preset", "bone", "--ascii",
            "--algorithm", "mc", "-o", stl.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    return pid;
  };
  // One full run for the duration, and the reference result.
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  waitpid(start(), &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  const double full_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const auto complete_size = fs::file_size(stl);

  int killed = 0;
  int killed_while_writing = 0;
  for (int attempt = 0; attempt < 50; ++attempt) {
    fs::remove(stl);
    const pid_t pid = start();
    const double at = full_ms * (0.3 + 0.75 * attempt / 50.0);  // late: during the writes
    std::this_thread::sleep_for(std::chrono::microseconds(static_cast<long>(at * 1000)));
    killed += ::kill(pid, SIGKILL) == 0;
    waitpid(pid, &status, 0);
    if (fs::exists(stl)) {
      EXPECT_EQ(fs::file_size(stl), complete_size) << "truncated output after a kill at " << at;
      const auto stats = nlohmann::json::parse(run("stats --json " + stl.string()).out);
      EXPECT_TRUE(stats["closed_manifold"].get<bool>());
    }
    const int left = left_over();
    EXPECT_LE(left, 1) << "earlier killed runs' temporary files were not removed";
    killed_while_writing += left;
  }
  EXPECT_GT(killed, 0);
  EXPECT_GT(killed_while_writing, 0);
  waitpid(start(), &status, 0);  // a run that completes removes the last left-over
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(left_over(), 0);
}

}  // namespace

namespace {

TEST(Cli, OutputDoesNotDependOnThreadCount) {
  const std::string sample = std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series";
  const fs::path out = fresh_dir("threads_out");
  for (const char* algorithm : {"mc", "tm"}) {
    for (const char* threads : {"1", "2", "3"}) {
      const fs::path stl = out / (std::string(algorithm) + threads + ".stl");
      ASSERT_EQ(run("convert " + sample + " --preset bone --algorithm " + algorithm +
                    " --threads " + threads + " -o " + stl.string()).exit_code, 0);
    }
    auto bytes = [&](const char* threads) {
      std::ifstream in(out / (std::string(algorithm) + threads + ".stl"), std::ios::binary);
      return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    EXPECT_EQ(bytes("1"), bytes("2")) << algorithm;
    EXPECT_EQ(bytes("1"), bytes("3")) << algorithm;
    EXPECT_GT(bytes("1").size(), 84u);
  }
}

}  // namespace

namespace {

TEST(Cli, CropBoxLeavesOutWhatIsOutside) {
  // The ball spans x = −97 … −91 mm; a box ending at x = −94 keeps about half of it.
  const fs::path dir = write_ball_series("crop");
  const fs::path out = fresh_dir("crop_out");
  ASSERT_EQ(run("convert " + dir.string() + " --iso 0 -o " + (out / "all.stl").string()).exit_code, 0);
  const CommandRun cropped = run("convert " + dir.string() + " --iso 0 --crop-mm -200,-200,-200,-94,200,200 -o " +
                                 (out / "half.stl").string());
  ASSERT_EQ(cropped.exit_code, 0) << cropped.out;
  const auto all = nlohmann::json::parse(run("stats --json " + (out / "all.stl").string()).out);
  const auto half = nlohmann::json::parse(run("stats --json " + (out / "half.stl").string()).out);
  EXPECT_TRUE(half["closed_manifold"].get<bool>());
  EXPECT_LT(half["volume_mm3"].get<double>(), 0.75 * all["volume_mm3"].get<double>());
  EXPECT_GT(half["volume_mm3"].get<double>(), 0.25 * all["volume_mm3"].get<double>());
}

}  // namespace

namespace {

nlohmann::json read_json(const fs::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

// --iso auto (issue 16 item 5): Otsu's threshold over the volume, printed and in the report.
TEST(Cli, IsoAutoOnTheSampleSeriesLandsBetweenAirAndSoftTissue) {
  const fs::path out = fresh_dir("iso_auto");
  const CommandRun r = run("convert " + std::string(TYPEMERGE_SOURCE_DIR) +
                           "/sample_series --iso auto -o " + (out / "skin.stl").string() +
                           " --report " + (out / "report.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("iso auto: Otsu's threshold"), std::string::npos) << r.out;
  const auto report = read_json(out / "report.json");
  const double threshold = report["auto_iso"]["threshold"].get<double>();
  EXPECT_EQ(report["auto_iso"]["units"], "HU");
  // Air is -1000 HU; the phantom's skin and soft tissue 0 to 60 HU.
  EXPECT_GT(threshold, -900);
  EXPECT_LT(threshold, -100);
  EXPECT_LT(report["auto_iso"]["lower_class_mean"].get<double>(), -900);
  EXPECT_GT(report["auto_iso"]["upper_class_mean"].get<double>(), -100);
  EXPECT_EQ(report["surfaces"][0]["hu_lo"].get<double>(), threshold);
  EXPECT_TRUE(report["surfaces"][0]["validity"]["closed_manifold"].get<bool>());
  EXPECT_TRUE(report["notes"].empty()) << report["notes"];
  // The same surface as the threshold given by hand (the printed value has 6 digits: compare
  // volumes, not bytes).
  char given[64];
  std::snprintf(given, sizeof given, "%.17g", threshold);
  ASSERT_EQ(run("convert " + std::string(TYPEMERGE_SOURCE_DIR) + "/sample_series --iso " + given +
                " -o " + (out / "given.stl").string()).exit_code, 0);
  const auto a = nlohmann::json::parse(run("stats --json " + (out / "skin.stl").string()).out);
  const auto b = nlohmann::json::parse(run("stats --json " + (out / "given.stl").string()).out);
  EXPECT_EQ(a["volume_mm3"], b["volume_mm3"]);
}

// An MR-like series: modality MR, background near 0 with noise, tissue around 600 in the
// scanner's units. Table removal (HU) is skipped with a note; the threshold is in its units.
TEST(Cli, IsoAutoOnAnMrLikeSeriesSkipsTheHuSteps) {
  const fs::path dir = fresh_dir("mr_like");
  typemerge::ct_writer::SeriesLayout layout;
  layout.uid_seed = "mr_like";
  layout.columns = 24;
  layout.rows = 24;
  layout.slices = 12;
  layout.slice_spacing = 2;
  layout.rescale_intercept = 0;
  layout.stored_value = [](int i, int j, int k) {
    const double d = std::hypot(i - 11.5, j - 11.5, (k - 5.5) * 2);
    const int noise = static_cast<int>(typemerge::ct_writer::fnv1a64(
                          std::to_string(i) + "," + std::to_string(j) + "," + std::to_string(k)) %
                      41);
    return (d < 8 ? 600 : 5) + noise;
  };
  for (auto spec : typemerge::ct_writer::make_axial_series(layout)) {
    spec.modality = "MR";
    typemerge::ct_writer::write_ct_slice(spec, dir / (spec.instance_number + ".dcm"));
  }
  const fs::path out = fresh_dir("mr_like_out");
  const CommandRun r = run("convert " + dir.string() + " --allow-non-ct --iso auto --remove-table " +
                           "--crop-tissue -o " + (out / "head.stl").string() + " --report " +
                           (out / "report.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("note: table removal skipped: the series is MR"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("note: tissue crop at Otsu's threshold"), std::string::npos) << r.out;
  const auto report = read_json(out / "report.json");
  EXPECT_EQ(report["auto_iso"]["units"], "volume values");
  const double threshold = report["auto_iso"]["threshold"].get<double>();
  EXPECT_GT(threshold, 100);
  EXPECT_LT(threshold, 550);
  EXPECT_EQ(report["preprocess"][0]["step"], "remove_outside_body");
  EXPECT_TRUE(report["preprocess"][0]["skipped"].get<bool>());
  EXPECT_EQ(report["notes"].size(), 2u);
  EXPECT_TRUE(report["surfaces"][0]["validity"]["closed_manifold"].get<bool>());
  // The ball of radius 8 mm: 4/3 π 8³ mm³ = 2.14 mL.
  EXPECT_NEAR(report["surfaces"][0]["volume_ml"].get<double>(), 2.14, 0.25);
}

TEST(Cli, IsoWantsANumberOrAuto) {
  const fs::path dir = write_ball_series("iso_word");
  const CommandRun r = run("convert " + dir.string() + " --iso automatic -o " +
                           (fresh_dir("iso_word_out") / "x.stl").string());
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("a number or 'auto'"), std::string::npos) << r.out;
}

}  // namespace
