// Batch planning, names, shards, manifest keys and summaries, on a generated study tree.
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <algorithm>
#include <fstream>
#include <set>

#include "app/batch_command.h"
#include "app/batch_manifest.h"
#include "app/batch_plan.h"
#include "app/batch_summary.h"
#include "app/child_process.h"
#include "app/memory_budget.h"
#include "app/cli_runner.h"
#include "app/study_tree.h"
#include "dicom/patient_identifiers.h"

namespace {

namespace fs = std::filesystem;
using namespace typemerge::app;

const fs::path& tree() {
  static const fs::path root = [] {
    const fs::path dir = typemerge::test::fresh_dir("plan_tree");
    typemerge::test::write_study_tree(dir);
    return dir;
  }();
  return root;
}

const typemerge::dicom::FolderScan& scan() {
  static const auto result = typemerge::dicom::scan_folder(tree(), {});
  return result;
}

std::string series_with_description(const std::string& description) {
  for (const auto& s : scan().series) {
    if (s.description == description) return s.id;
  }
  return "none";
}

const StudyPlan* find_plan(const std::vector<StudyPlan>& plans, const std::string& folder) {
  for (const StudyPlan& plan : plans) {
    if (plan.folder == folder) return &plan;
  }
  return nullptr;
}

TEST(BatchPlan, FindsEveryStudyAndChoosesItsSeriesByTheDocumentedRule) {
  const auto plans =
      plan_studies(scan(), {}, kDefaultNamePattern, typemerge::dicom::patient_identifiers);
  ASSERT_EQ(plans.size(), 5u);
  const StudyPlan* a = find_plan(plans, "siteA/p01/studyA");
  const StudyPlan* b = find_plan(plans, "siteA/p02/studyB");
  const StudyPlan* d = find_plan(plans, "siteB/studyD/s1");
  ASSERT_TRUE(a && b && d);
  EXPECT_EQ(a->series_id, series_with_description("thin 1mm"));  // most slices; not the scout
  EXPECT_EQ(b->series_id, series_with_description("sharp 1mm"));  // same count, thinner
  EXPECT_EQ(a->voxels, 24u * 24u * 14u);
  EXPECT_EQ(a->files.size(), 14u + 7u + 1u);  // every file of the study, localizer included
  EXPECT_TRUE(d->series_id.empty());
  EXPECT_NE(d->refusal.find("missing"), std::string::npos) << d->refusal;
  EXPECT_EQ(a->output_name, "siteA/p01/studyA");
}

TEST(BatchPlan, FiltersRestrictTheChoiceAndSayWhenNothingMatches) {
  SeriesFilter soft;
  soft.kernel_regex = "^soft$";  // case-insensitive
  auto plans = plan_studies(scan(), soft, kDefaultNamePattern);
  EXPECT_EQ(find_plan(plans, "siteA/p02/studyB")->series_id, series_with_description("soft 2mm"));
  const StudyPlan* a = find_plan(plans, "siteA/p01/studyA");
  EXPECT_TRUE(a->series_id.empty());
  EXPECT_EQ(a->refusal, "no usable series matches the series filter");

  SeriesFilter thick;
  thick.description_regex = "THICK";
  plans = plan_studies(scan(), thick, kDefaultNamePattern);
  EXPECT_EQ(find_plan(plans, "siteA/p01/studyA")->series_id, series_with_description("thick 2mm"));

  SeriesFilter thin;
  thin.max_thickness_mm = 1.2;
  plans = plan_studies(scan(), thin, kDefaultNamePattern);
  EXPECT_EQ(find_plan(plans, "siteA/p01/studyA")->series_id, series_with_description("thin 1mm"));
  EXPECT_EQ(find_plan(plans, "siteA/p02/studyB")->series_id, series_with_description("sharp 1mm"));
  thin.min_thickness_mm = 1.8;
  thin.max_thickness_mm.reset();
  plans = plan_studies(scan(), thin, kDefaultNamePattern);
  EXPECT_EQ(find_plan(plans, "siteA/p02/studyB")->series_id, series_with_description("soft 2mm"));

  SeriesFilter broken;
  broken.description_regex = "([";
  EXPECT_THROW(broken.accepts(scan().series.front()), std::invalid_argument);
}

TEST(BatchPlan, FolderNamesSpellingThePatientAreMaskedInNamesAndInputs) {
  const auto plans =
      plan_studies(scan(), {}, kDefaultNamePattern, typemerge::dicom::patient_identifiers);
  const auto c = std::find_if(plans.begin(), plans.end(), [](const StudyPlan& p) {
    return p.folder == "siteB/DOE_JOHN/studyC/s1";
  });
  ASSERT_NE(c, plans.end());
  EXPECT_EQ(c->output_name, "siteB/study-" + c->study_id + "/studyC/s1");
  EXPECT_EQ(c->shown_folder, "siteB/study-" + c->study_id + "/studyC/s1");
  for (const StudyPlan& p : plans) {
    EXPECT_EQ(p.output_name.find("DOE"), std::string::npos);
    EXPECT_EQ(p.shown_folder.find("JOHN"), std::string::npos);
  }
}

TEST(BatchPlan, NamesStayInsideTheOutputFolderAndNeverCollide) {
  EXPECT_EQ(sanitise_component(".."), "_");
  EXPECT_EQ(sanitise_component("."), "_");
  EXPECT_EQ(sanitise_component(".hidden"), "_hidden");
  EXPECT_EQ(sanitise_component("a b;c$(rm)"), "a_b_c__rm_");
  EXPECT_EQ(sanitise_component(std::string(300, 'x')).size(), 96u);

  auto plans = plan_studies(scan(), {}, "/../{folder}/../../{study}//");
  for (const StudyPlan& p : plans) {
    EXPECT_EQ(p.output_name.rfind("_/site", 0), 0u) << p.output_name;  // ".." became "_"
    EXPECT_EQ(p.output_name.find(".."), std::string::npos) << p.output_name;
    EXPECT_EQ(p.output_name.find("//"), std::string::npos) << p.output_name;
  }
  plans = plan_studies(scan(), {}, "same");
  std::set<std::string> names;
  for (const StudyPlan& p : plans) {
    names.insert(p.output_name);
    EXPECT_EQ(p.output_name, "same-" + p.study_id);
  }
  EXPECT_EQ(names.size(), plans.size());
  plans = plan_studies(scan(), {}, "{study}/{series}/bone.stl");
  for (const StudyPlan& p : plans) {
    EXPECT_EQ(p.output_name.substr(p.output_name.size() - 9), "bone.stl_") << p.output_name;
  }
}

TEST(BatchPlan, ShardsCoverEveryStudyExactlyOnceAndAreBalanced) {
  std::vector<int> counts(3, 0);
  for (int i = 0; i < 600; ++i) {
    const std::string id = study_id_of("1.2.3." + std::to_string(i));
    int owners = 0;
    for (int k = 1; k <= 3; ++k) {
      if (in_shard(id, k, 3)) {
        ++owners;
        ++counts[k - 1];
      }
    }
    EXPECT_EQ(owners, 1);
    EXPECT_TRUE(in_shard(id, 1, 1));
  }
  for (int c : counts) EXPECT_GT(c, 150);
}

TEST(BatchManifest, KeyFollowsContentAndParametersNotFileNames) {
  const fs::path dir = typemerge::test::fresh_dir("manifest_key");
  std::ofstream(dir / "a") << "alpha";
  std::ofstream(dir / "b") << "beta";
  const StudyKey first = study_key({dir / "a", dir / "b"}, "--preset=bone\n", {});
  EXPECT_EQ(first.key.size(), 16u);
  EXPECT_EQ(study_key({dir / "b", dir / "a"}, "--preset=bone\n", {}).key, first.key);
  EXPECT_NE(study_key({dir / "a", dir / "b"}, "--preset=skin\n", {}).key, first.key);
  fs::rename(dir / "b", dir / "c");
  EXPECT_EQ(study_key({dir / "a", dir / "c"}, "--preset=bone\n", {}).key, first.key);
  std::ofstream(dir / "c") << "gamma";
  EXPECT_NE(study_key({dir / "a", dir / "c"}, "--preset=bone\n", {}).key, first.key);
  // Stamps with the same size and time are trusted: the hash is taken from them.
  StudyKey now = study_key({dir / "a"}, "", {});
  std::vector<FileStamp> forged = now.stamps;
  forged[0].hash ^= 1;
  EXPECT_NE(study_key({dir / "a"}, "", forged).key, now.key);
  EXPECT_THROW(study_key({dir / "missing"}, "", {}), std::runtime_error);
  // Paths are kept as hashes only: folder names can spell patient names.
  EXPECT_EQ(now.stamps[0].path.find("manifest_key"), std::string::npos);
}

TEST(BatchManifest, RecordsRoundTripAndDetectChangedOutputs) {
  const fs::path out = typemerge::test::fresh_dir("manifest_record");
  fs::create_directories(out / "s");
  std::ofstream(out / "s" / "bone.stl") << "12345";
  StudyRecord record{"abc", "0123456789abcdef", "s", {{"s/bone.stl", 5}}, {{"h", 5, 7, 9}}, "{}"};
  write_study_record(out, record);
  const auto read = read_study_record(out, "abc");
  ASSERT_TRUE(read);
  EXPECT_EQ(read->key, record.key);
  EXPECT_EQ(read->stamps[0].hash, 9u);
  EXPECT_TRUE(outputs_intact(out, *read));
  std::ofstream(out / "s" / "bone.stl") << "1234";
  EXPECT_FALSE(outputs_intact(out, *read));
  std::ofstream(batch_state_folder(out) / "studies" / "abc.json") << "{ broken";
  EXPECT_FALSE(read_study_record(out, "abc"));
}

TEST(BatchSummary, CsvQuotesAndShardMergeChecksCompleteness) {
  const fs::path out = typemerge::test::fresh_dir("summary_merge");
  StudyOutcome a;
  a.input = "x";
  a.study = "s1";
  a.output_name = "x";
  a.status = StudyStatus::failed;
  a.reason = "bad, very \"bad\"";
  write_summary(out, "summary.shard-1-of-2", {a}, "1/2");
  const std::string csv = typemerge::test::read_file_bytes(out / "summary.shard-1-of-2.csv");
  EXPECT_NE(csv.find("\"bad, very \"\"bad\"\"\""), std::string::npos) << csv;
  EXPECT_THROW(merge_shard_summaries(out), std::runtime_error);  // shard 2 missing
  StudyOutcome b = a;
  b.study = "s2";
  b.output_name = "w";
  b.status = StudyStatus::converted;
  b.surfaces = {{"bone", "w/bone.stl", 12, 1.5, true}};
  write_summary(out, "summary.shard-2-of-2", {b}, "2/2");
  const auto merged = merge_shard_summaries(out);
  ASSERT_EQ(merged.size(), 2u);
  EXPECT_EQ(merged[0].output_name, "w");  // sorted by output name
  EXPECT_EQ(merged[0].surfaces[0].triangles, 12u);
  EXPECT_TRUE(fs::exists(out / "summary.json"));
  write_summary(out, "summary.shard-1-of-3", {a}, "1/3");
  EXPECT_THROW(merge_shard_summaries(out), std::runtime_error);  // 2 and 3 shards mixed
}

TEST(BatchCommand, MemorySizesParse) {
  EXPECT_EQ(parse_memory_size("512M"), 512ull << 20);
  EXPECT_EQ(parse_memory_size("8G"), 8ull << 30);
  EXPECT_EQ(parse_memory_size("1.5k"), 1536u);
  EXPECT_EQ(parse_memory_size("4096"), 4096u);
  for (const char* bad : {"", "G", "-1G", "0", "8X", "nan", "1e30T"}) {
    EXPECT_THROW(parse_memory_size(bad), std::invalid_argument) << bad;
  }
}

TEST(BatchCommand, WorkingVoxelsCountTheResampledGrid) {
  EXPECT_EQ(working_voxels({512, 512, 100}, {0.8, 0.8, 1.25}, 0), 512u * 512u * 100u);
  // 409.6 × 409.6 × 125 mm in 0.5 mm voxels: 821 × 821 × 251 more (ceil + 1 per axis).
  EXPECT_EQ(working_voxels({512, 512, 100}, {0.8, 0.8, 1.25}, 0.5),
            512u * 512u * 100u + 821u * 821u * 251u);
  // An absurd voxel size saturates instead of wrapping around.
  EXPECT_GT(working_voxels({512, 512, 100}, {0.8, 0.8, 1.25}, 1e-9), std::uint64_t{1} << 59);
}

// The isolation the batch relies on: exit codes, signals (a crash), captured output, kill.
std::optional<ChildResult> wait_for(ChildProcess& child) {
  for (int i = 0; i < 2000; ++i) {
    if (auto result = child.poll()) return result;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return std::nullopt;
}

TEST(ChildProcess, ReportsExitCodesSignalsAndOutputWithoutAShell) {
  const fs::path dir = typemerge::test::fresh_dir("child");
  ChildProcess ok({{"/bin/sh", "-c", "echo out; echo err >&2; exit 3"}, dir / "ok.txt"});
  auto result = wait_for(ok);
  ASSERT_TRUE(result);
  EXPECT_TRUE(result->exited);
  EXPECT_EQ(result->exit_code, 3);
  EXPECT_EQ(typemerge::test::read_file_bytes(dir / "ok.txt"), "out\nerr\n");

  ChildProcess crash({{"/bin/sh", "-c", "kill -SEGV $$"}, dir / "crash.txt"});
  result = wait_for(crash);
  ASSERT_TRUE(result);
  EXPECT_FALSE(result->exited);
  EXPECT_EQ(result->signal, SIGSEGV);

  // Arguments reach the program as they are: no shell expands them.
  ChildProcess literal({{"/bin/echo", "$HOME", "*", "a;b"}, dir / "literal.txt"});
  ASSERT_TRUE(wait_for(literal));
  EXPECT_EQ(typemerge::test::read_file_bytes(dir / "literal.txt"), "$HOME * a;b\n");

  ChildProcess hang({{"/bin/sleep", "30"}, dir / "hang.txt"});
  hang.kill();
  result = wait_for(hang);
  ASSERT_TRUE(result);
  EXPECT_EQ(result->signal, SIGKILL);

  ChildProcess missing({{"/nonexistent/program"}, dir / "missing.txt"});
  result = wait_for(missing);
  ASSERT_TRUE(result);
  EXPECT_EQ(result->exit_code, 127);
}

}  // namespace
