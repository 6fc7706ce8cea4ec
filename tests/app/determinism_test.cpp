// Byte-identical outputs (issue 6): the STL surfaces, the PNG previews, the NRRD volume,
// `info --json`, the JSON report and the batch summary, JSON and CSV, with its entries for
// folders no study came of (minus timing and memory fields, which are measurements) are the
// same across reruns, CPU counts, file names and directory order of the input, the locale
// (C against a comma-decimal German one) and the time zone.
//
// Threads: convert has no thread option (extraction runs serially in the pipeline; the core's
// ExtractOptions::threads is checked for identical output in tests/core). The loader reads
// and decodes with TBB over all CPUs, so one run is pinned to a single CPU with taskset.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "app/cli_runner.h"
#include "app/study_tree.h"
#include "ct_writer/ct_writer.h"

namespace {

namespace fs = std::filesystem;
namespace ctw = typemerge::ct_writer;
using typemerge::test::fresh_dir;
using typemerge::test::read_file_bytes;
using typemerge::test::run_cli;

std::vector<ctw::CtSliceSpec> study_specs() {
  ctw::SeriesLayout layout;
  layout.uid_seed = "determinism";
  layout.columns = 24;
  layout.rows = 22;
  layout.slices = 12;
  layout.pixel_spacing = {0.7, 0.8};
  layout.slice_spacing = 1.25;
  layout.origin = {-10.5, 20.25, -30};
  // Smooth values with fractions of a HU after rescale (slope 0.5), so formatting of
  // decimals matters everywhere.
  layout.rescale_slope = 0.5;
  layout.hu = [](int i, int j, int k) {
    const double d = std::hypot(i - 11.3, (j - 10.7) * 1.1, (k - 5.6) * 1.6);
    return d < 4.2 ? 1150.5 - 20 * d : d < 8.5 ? 35.5 + 3 * d : -1000.0;
  };
  return ctw::make_axial_series(layout);
}

// The same slices under other names, written in reverse order into two folders.
void write_study(const fs::path& dir, bool shuffled) {
  const auto specs = study_specs();
  if (!shuffled) {
    ctw::write_series(specs, dir);
    return;
  }
  for (std::size_t n = specs.size(); n-- > 0;) {
    const fs::path folder = dir / (n % 2 ? "a" : "z");
    fs::create_directories(folder);
    const std::uint64_t hash = ctw::fnv1a64("shuffle" + std::to_string(n));
    ctw::write_ct_slice(specs[n], folder / ("x" + std::to_string(hash % 100000) + ".ima"));
  }
}

// Drops every timing field ("ms", "*_ms") from a report.
void strip_timings(nlohmann::json& value) {
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end();) {
      const std::string& key = it.key();
      const bool timing =
          key == "ms" || (key.size() > 3 && key.compare(key.size() - 3, 3, "_ms") == 0);
      if (timing) {
        it = value.erase(it);
      } else {
        strip_timings(*it);
        ++it;
      }
    }
  } else if (value.is_array()) {
    for (auto& item : value) strip_timings(item);
  }
}

// A batch input: the study, a folder of damaged files and notes, a folder of notes.
const fs::path& batch_tree() {
  static const fs::path root = [] {
    const fs::path dir = fresh_dir("determinism_batch_tree");
    write_study(dir / "study", false);
    typemerge::test::write_damaged_dicom(dir / "damaged" / "a");
    typemerge::test::write_damaged_dicom(dir / "damaged" / "b");
    { std::ofstream(dir / "damaged" / "notes.txt") << "notes\n"; }
    fs::create_directories(dir / "docs");
    { std::ofstream(dir / "docs" / "readme.txt") << "readme\n"; }
    return dir;
  }();
  return root;
}

// The batch summary of `batch_tree()` without its measurements: seconds, CPU seconds and peak
// memory (the last three CSV columns, numbers, never quoted).
void add_batch_summary(std::map<std::string, std::string>& result, const std::string& name,
                       const std::string& environment, const std::string& wrapper) {
  const fs::path out = fresh_dir("determinism_batch_" + name);
  const auto run = run_cli("batch " + batch_tree().string() + " --preset bone --out " +
                               out.string() + " --threads 1",
                           environment, wrapper);
  EXPECT_EQ(run.exit_code, 5) << name << ": " << run.err;  // the damaged folder fails it
  auto summary = nlohmann::json::parse(read_file_bytes(out / "summary.json"));
  for (auto& entry : summary["results"]) {
    for (const char* measured : {"seconds", "cpu_seconds", "peak_memory_mb"}) entry.erase(measured);
  }
  result["batch/summary.json"] = summary.dump(1);
  std::string csv;
  std::istringstream lines(read_file_bytes(out / "summary.csv"));
  for (std::string line; std::getline(lines, line);) {
    for (int field = 0; field < 3; ++field) line.erase(line.rfind(','));
    csv += line + "\n";
  }
  result["batch/summary.csv"] = csv;
}

// Every output of one configuration, by name.
std::map<std::string, std::string> outputs(const std::string& name, const fs::path& study,
                                           const std::string& environment,
                                           const std::string& wrapper = "") {
  const fs::path out = fresh_dir("determinism_out_" + name);
  std::map<std::string, std::string> result;
  const std::string in = study.string();
  const auto info = run_cli("info --json " + in, environment, wrapper);
  EXPECT_EQ(info.exit_code, 0) << name << ": " << info.err;
  result["info.json"] = info.out;
  for (const std::string& command : {
           "volume " + in + " -o " + (out / "volume.nrrd").string(),
           "volume " + in + " --float -o " + (out / "volume_float.nrrd").string(),
           "convert " + in + " --preset bone,skin -o " + (out / "presets").string() +
               " --preview --report " + (out / "report.json").string(),
           "convert " + in + " --iso 300.5 --algorithm mc --finish none --ascii -o " +
               (out / "ascii.stl").string(),
           "convert " + in + " --window 0,200 --smooth 3 --voxel-size 0.9 -o " +
               (out / "window.stl").string() + " --report " + (out / "window.json").string(),
           "convert " + in + " --iso 300.5 -o " + (out / "mesh.3mf").string(),
           "convert " + in + " --preset bone,skin --center -o " + (out / "presets.3mf").string(),
           "convert " + in + " --iso auto --hollow 1.5 -o " + (out / "hollow.stl").string() +
               " --report " + (out / "hollow.json").string(),
       }) {
    const auto r = run_cli(command, environment, wrapper);
    EXPECT_EQ(r.exit_code, 0) << name << ": " << command << "\n" << r.err;
  }
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    if (!entry.is_regular_file()) continue;
    const std::string file = entry.path().lexically_relative(out).string();
    std::string bytes = read_file_bytes(entry.path());
    if (entry.path().extension() == ".json") {
      auto report = nlohmann::json::parse(bytes);
      strip_timings(report);
      bytes = report.dump(1);
    }
    result[file] = std::move(bytes);
  }
  add_batch_summary(result, name, environment, wrapper);
  return result;
}

void expect_same(const std::map<std::string, std::string>& reference,
                 const std::map<std::string, std::string>& other, const std::string& what) {
  ASSERT_EQ(reference.size(), other.size()) << what;
  for (const auto& [file, bytes] : reference) {
    const auto found = other.find(file);
    ASSERT_NE(found, other.end()) << what << ": no " << file;
    if (found->second == bytes) continue;
    std::size_t at = 0;
    while (at < bytes.size() && at < found->second.size() && bytes[at] == found->second[at]) ++at;
    ADD_FAILURE() << what << ": " << file << " differs from byte " << at << " ("
                  << bytes.size() << " vs " << found->second.size() << " bytes)";
  }
}

// A comma-decimal locale the child processes can use: de_DE.UTF-8 if installed (install_deps
// generates it), else compiled with localedef into a private folder (LOCPATH). Empty with
// `why` set if neither works.
//
// With LOCPATH set, glibc's newlocale (called by libp11-kit, a transitive dependency, while it
// loads) leaks its copy of the path, 49 bytes once per process; LeakSanitizer would abort the
// sanitizer build on it, so exactly that allocation is suppressed in that case.
std::string german_locale_environment(std::string& why) {
  const fs::path folder = fresh_dir("locales");
  const fs::path suppressions = folder / "lsan.supp";
  std::ofstream(suppressions) << "leak:__argz_add_sep\n";
  const std::vector<std::string> candidates = {
      "LC_ALL=de_DE.UTF-8",
      "LOCPATH=" + folder.string() + " LC_ALL=de_DE.UTF-8 LSAN_OPTIONS=suppressions=" +
          suppressions.string(),
  };
  auto radix = [](const std::string& environment) {
    FILE* pipe = popen(("env " + environment + " locale -k decimal_point 2>/dev/null").c_str(), "r");
    if (pipe == nullptr) return std::string();
    char line[128] = {};
    const bool got = std::fgets(line, sizeof line, pipe) != nullptr;
    pclose(pipe);
    return got ? std::string(line) : std::string();
  };
  if (radix(candidates[0]).find("\",\"") != std::string::npos) return candidates[0];
  fs::create_directories(folder);
  const std::string command = "localedef -i de_DE -f UTF-8 " + (folder / "de_DE.UTF-8").string() +
                              " >/dev/null 2>&1";
  const int status = std::system(command.c_str());
  if (radix(candidates[1]).find("\",\"") != std::string::npos) return candidates[1];
  why = "no comma-decimal locale: de_DE.UTF-8 is not installed and `" + command +
        "` exited with " + std::to_string(status) +
        " (install the Debian package `locales`, as scripts/install_deps.sh does)";
  return {};
}

// The study and its reference outputs, made by the first test that needs them (in the test,
// not in SetUpTestSuite, whose failures ctest would report as skipped tests).
class Determinism : public ::testing::Test {
 protected:
  void SetUp() override {
    static const fs::path study = [] {
      const fs::path dir = fresh_dir("determinism_study");
      write_study(dir, false);
      return dir;
    }();
    static const auto reference = outputs("reference", study, "LC_ALL=C TZ=UTC");
    study_ = &study;
    reference_ = &reference;
    ASSERT_EQ(reference_->size(), 17u) << "the reference run did not write every output";
  }
  const fs::path* study_ = nullptr;
  const std::map<std::string, std::string>* reference_ = nullptr;
};

TEST_F(Determinism, ReferenceRunWroteEverything) {
  // info, NRRD ×2, bone and skin STL and PNG, three reports, three more STL (the last with
  // --iso auto --hollow), two 3MF, the batch summary as JSON and CSV (checked in SetUp).
  for (const auto& [file, bytes] : *reference_) EXPECT_GT(bytes.size(), 100u) << file;
  const std::string& summary = reference_->at("batch/summary.json");
  EXPECT_NE(summary.find("\"no_study\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"no_ct\""), std::string::npos) << summary;
}

TEST_F(Determinism, RerunGivesTheSameBytes) {
  expect_same(*reference_, outputs("rerun", *study_, "LC_ALL=C TZ=UTC"), "rerun");
}

TEST_F(Determinism, OneCpuGivesTheSameBytes) {
  if (std::system("taskset -c 0 true >/dev/null 2>&1") != 0) {
    GTEST_FAIL() << "taskset (util-linux) cannot pin to CPU 0 here";
  }
  expect_same(*reference_, outputs("one_cpu", *study_, "LC_ALL=C TZ=UTC", "taskset -c 0"),
              "taskset -c 0");
}

TEST_F(Determinism, FileNamesAndOrderDoNotMatter) {
  const fs::path shuffled = fresh_dir("determinism_shuffled");
  write_study(shuffled, true);
  expect_same(*reference_, outputs("shuffled", shuffled, "LC_ALL=C TZ=UTC"), "shuffled input");
}

TEST_F(Determinism, CommaDecimalLocaleGivesTheSameBytes) {
  std::string why;
  const std::string german = german_locale_environment(why);
  ASSERT_FALSE(german.empty()) << why;  // fail, not skip: the property would go unchecked
  expect_same(*reference_, outputs("german", *study_, german + " TZ=UTC"), german);
}

TEST_F(Determinism, TimeZoneDoesNotMatter) {
  ASSERT_TRUE(fs::exists("/usr/share/zoneinfo/Pacific/Auckland")) << "tzdata is missing";
  expect_same(*reference_, outputs("auckland", *study_, "LC_ALL=C TZ=Pacific/Auckland"),
              "TZ=Pacific/Auckland");
}

}  // namespace
