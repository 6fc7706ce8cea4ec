// Batch planning, names, shards, manifest keys and summaries, on a generated study tree.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <algorithm>
#include <fstream>
#include <map>
#include <set>

#include "app/batch_command.h"
#include "app/batch_folders.h"
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
  // Its integer rescale loads as int16: the memory estimate that schedules it counts 2 bytes a
  // voxel for the volume, as convert's own does (app/memory_budget.h).
  EXPECT_TRUE(a->int16_samples);
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

// The shared tree holds two folders whose files went into no study: ROOT (README.txt) and
// siteA/p01 (notes.txt, beside the folder of study A). Folders holding a study's files, such
// as siteA/p01/studyA/scout, are not listed.
TEST(BatchFolders, ListsTheFoldersNoStudyCameFromByTheirIds) {
  const auto plans = plan_studies(scan(), {}, kDefaultNamePattern);
  const auto folders = folders_without_study(scan(), plans);
  ASSERT_EQ(folders.size(), 2u);
  std::set<std::string> folder_names;
  for (const auto& f : folders) {
    folder_names.insert(f.folder.generic_string());
    EXPECT_EQ(f.folder_id, folder_id_of(f.folder));
    EXPECT_EQ(f.reason(), "1 non-DICOM file");
    EXPECT_FALSE(f.counts_as_failure());
    const StudyOutcome entry = folder_outcome(f);
    EXPECT_EQ(entry.status, StudyStatus::no_ct);
    EXPECT_EQ(entry.input, "folder-" + f.folder_id);
    EXPECT_TRUE(entry.study.empty() && entry.output_name.empty());
  }
  EXPECT_EQ(folder_names, (std::set<std::string>{"", "siteA/p01"}));
  EXPECT_LT(folders[0].folder_id, folders[1].folder_id);  // sorted by id
}

TEST(BatchFolders, IdsAreStableHashesOfTheRelativeFolder) {
  const std::string id = folder_id_of("siteA/p01");
  EXPECT_EQ(id.size(), 12u);
  EXPECT_EQ(id.find_first_not_of("0123456789abcdef"), std::string::npos) << id;
  EXPECT_EQ(folder_id_of("siteA/p01/"), id);
  EXPECT_EQ(folder_id_of("siteA/./p01"), id);
  EXPECT_EQ(folder_id_of(""), folder_id_of("."));
  EXPECT_NE(folder_id_of("siteA/p02"), id);
  EXPECT_NE(folder_id_of("sitea/p01"), id);
}

// Each kind of skipped file, its count and whether it fails the batch (the table in
// batch_folders.cpp, README "Batch"): made-up scan results, one folder per case.
TEST(BatchFolders, CountsFilesByKindAndOnlyLostDataFails) {
  using typemerge::dicom::FileKind;
  typemerge::dicom::FolderScan made_up;
  made_up.root = tree();
  made_up.skipped = {
      {"damaged/a", FileKind::unreadable, "damaged DICOM file: x", ""},
      {"damaged/b", FileKind::unreadable, "truncated file: y", ""},
      {"damaged/c", FileKind::unreadable, "refused before parsing: z", ""},
      {"damaged/notes.txt", FileKind::not_dicom, "not a DICOM file", ""},
      {"damaged/more.txt", FileKind::not_dicom, "not a DICOM file", ""},
      {"mr/1", FileKind::other_image, "modality MR, not CT", "MR"},
      {"mr/2", FileKind::other_image, "modality MR, not CT", "MR"},
      {"mr/3", FileKind::other_image, "modality PT, not CT", "PT"},
      {"mr/4", FileKind::other_image, "modality (none), not CT", "(none)"},
      {"mr/5", FileKind::other_image, "modality ..., not CT", "DOE^JOHN"},
      {"cd/DICOMDIR", FileKind::non_image, "DICOMDIR (media directory)", ""},
      {"cd/sc", FileKind::other_image, "secondary capture image", ""},
      {"cd/readme", FileKind::not_dicom, "not a DICOM file", ""},
      {"ct/1", FileKind::ct_image, "missing ImagePositionPatient", ""},
      {"study/stray.txt", FileKind::not_dicom, "not a DICOM file", ""},
  };
  StudyPlan plan;  // a study with a file in "study": its folder is accounted for by the study
  plan.files = {tree() / "study" / "im0"};
  const auto folders = folders_without_study(made_up, {plan});
  std::map<std::string, const FolderWithoutStudy*> by_name;
  for (const auto& f : folders) by_name[f.folder.generic_string()] = &f;
  ASSERT_EQ(by_name.size(), 4u);
  EXPECT_FALSE(by_name.count("study"));

  const FolderWithoutStudy& damaged = *by_name.at("damaged");
  EXPECT_EQ(damaged.reason(), "3 unreadable DICOM files; 2 non-DICOM files");
  ASSERT_EQ(damaged.skipped.size(), 2u);
  EXPECT_EQ(damaged.skipped[0].files, 3u);
  EXPECT_TRUE(damaged.skipped[0].counts_as_failure);
  EXPECT_FALSE(damaged.skipped[1].counts_as_failure);
  EXPECT_TRUE(damaged.counts_as_failure());
  EXPECT_EQ(folder_outcome(damaged).status, StudyStatus::no_study);

  // A hostile Modality is not repeated, a missing one not invented.
  const FolderWithoutStudy& mr = *by_name.at("mr");
  EXPECT_EQ(mr.reason(),
            "2 images of another modality, not CT (use --allow-non-ct); "
            "2 MR images, not CT (use --allow-non-ct); 1 PT image, not CT (use --allow-non-ct)");
  EXPECT_FALSE(mr.counts_as_failure());
  EXPECT_EQ(folder_outcome(mr).status, StudyStatus::no_ct);

  const FolderWithoutStudy& cd = *by_name.at("cd");
  EXPECT_EQ(cd.reason(),
            "1 image that is not a CT slice (secondary capture or colour); "
            "1 DICOM file without pixel data (DICOMDIR, report, ...); 1 non-DICOM file");
  EXPECT_FALSE(cd.counts_as_failure());

  const FolderWithoutStudy& ct = *by_name.at("ct");
  EXPECT_EQ(ct.reason(), "1 CT image that cannot be used");
  EXPECT_TRUE(ct.counts_as_failure());
}

TEST(BatchSummary, FolderEntriesRoundTripAndComeAfterTheStudies) {
  const fs::path out = typemerge::test::fresh_dir("summary_folders");
  StudyOutcome study;
  study.input = "zz";
  study.study = "s1";
  study.output_name = "zz";
  study.status = StudyStatus::converted;
  StudyOutcome damaged;
  damaged.input = "folder-000000000002";
  damaged.status = StudyStatus::no_study;
  damaged.reason = "3 unreadable DICOM files";
  damaged.skipped = {{3, "unreadable DICOM files", true}};
  StudyOutcome notes = damaged;
  notes.input = "folder-000000000001";
  notes.status = StudyStatus::no_ct;
  notes.reason = "1 non-DICOM file";
  notes.skipped = {{1, "non-DICOM file", false}};
  const StudyOutcome back = outcome_from_json(outcome_json(damaged));
  EXPECT_EQ(back.status, StudyStatus::no_study);
  ASSERT_EQ(back.skipped.size(), 1u);
  EXPECT_EQ(back.skipped[0].files, 3u);
  EXPECT_TRUE(back.skipped[0].counts_as_failure);
  EXPECT_TRUE(outcome_from_json(R"({"input":"a","study":"s","series":"","output":"a",)"
                                R"("status":"failed","reason":"","surfaces":[],"seconds":0,)"
                                R"("cpu_seconds":0,"peak_memory_mb":0})")
                  .skipped.empty());  // a record written before folders were listed

  const BatchTotals totals = totals_of({study, damaged, notes});
  EXPECT_EQ(totals.studies(), 1u);
  EXPECT_EQ(totals.no_study, 1u);
  EXPECT_EQ(totals.no_ct, 1u);
  write_summary(out, "summary", {damaged, notes, study}, "");
  const auto json = nlohmann::json::parse(typemerge::test::read_file_bytes(out / "summary.json"));
  EXPECT_EQ(json["studies"], 1);
  EXPECT_EQ(json["no_study"], 1);
  EXPECT_EQ(json["no_ct"], 1);
  ASSERT_EQ(json["results"].size(), 3u);
  EXPECT_EQ(json["results"][0]["input"], "zz");
  EXPECT_EQ(json["results"][1]["input"], "folder-000000000001");
  EXPECT_EQ(json["results"][2]["skipped"][0]["reason"], "unreadable DICOM files");
  const std::string csv = typemerge::test::read_file_bytes(out / "summary.csv");
  EXPECT_NE(csv.find("\nfolder-000000000002,,,,no_study,3 unreadable DICOM files,"),
            std::string::npos) << csv;

  // Shards: two folders without a study id are not "the same study in two shards".
  write_summary(out, "summary.shard-1-of-2", {study, notes}, "1/2");
  write_summary(out, "summary.shard-2-of-2", {damaged}, "2/2");
  EXPECT_EQ(merge_shard_summaries(out).size(), 3u);
  write_summary(out, "summary.shard-2-of-2", {damaged, notes}, "2/2");
  EXPECT_THROW(merge_shard_summaries(out), std::runtime_error);  // a folder in both shards
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

// A study's convert child: its series, the batch's options, the output and report under its
// work folder, the report without the sampled distances, its threads and memory limit.
TEST(BatchChild, ConvertArgumentsAskForTheReportWithoutDistances) {
  StudyPlan plan;
  plan.source = StudySource::dicom;
  plan.series_id = "s1234";
  plan.output_name = "ward/study";
  BatchOptions options;
  options.surface_arguments = {"--preset", "bone"};
  const fs::path work = fs::path("work") / "abc";
  const std::vector<std::string> argv =
      study_convert_arguments("root/ward", plan, options, work, 2, 1u << 30);
  auto after = [&](const std::string& flag) {
    const auto it = std::find(argv.begin(), argv.end(), flag);
    return it == argv.end() || it + 1 == argv.end() ? std::string("(absent)") : *(it + 1);
  };
  ASSERT_GE(argv.size(), 2u);
  EXPECT_EQ(argv[0], "convert");
  EXPECT_EQ(argv[1], fs::path("root/ward").string());
  EXPECT_EQ(after("--series"), "s1234");
  EXPECT_EQ(after("--preset"), "bone");
  EXPECT_EQ(after("-o"), (work / "out").string());
  EXPECT_EQ(after("--report"), (work / "report.json").string());
  EXPECT_EQ(after("--threads"), "2");
  EXPECT_NE(std::find(argv.begin(), argv.end(), "--report-without-distances"), argv.end());
  EXPECT_NE(std::find(argv.begin(), argv.end(), "--max-memory=1073741824"), argv.end());
  // A 3MF batch writes one package named like the study's output folder.
  options.format = "3mf";
  EXPECT_EQ(study_convert_arguments("root/ward", plan, options, work, 2, 1u << 30)[
                static_cast<std::size_t>(
                    std::find(argv.begin(), argv.end(), "-o") - argv.begin()) + 1],
            (work / "out" / "study.3mf").string());
}

}  // namespace
