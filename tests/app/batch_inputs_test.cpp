// `typemerge batch` over a tree holding, beside a DICOM series, a grey NIfTI named the way
// dcm2niix names files (protocol, acquisition time, series number), an integer NIfTI label map
// in a folder spelling the patient's name, a 3D Slicer .seg.nrrd, a ZIP of a DICOM series and
// (with the shared data) a DICOM SEG beside its CT series: each file a study of its own,
// converted (label mode for segmentations and, with --labels, for label maps), accounted in
// the summary, named without patient data, and up to date on a rerun. All but the SEG are
// written here, so the test runs without the shared data.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "app/batch_files.h"
#include "app/batch_outputs.h"
#include "app/cli_runner.h"
#include "app/study_tree.h"
#include "support/volume_file_writers.h"
#include "zip_input/zip_maker.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using typemerge::test::fresh_dir;
using typemerge::test::outputs_of;
using typemerge::test::run_cli;
using typemerge::test::summary_of;
namespace test = typemerge::test;
namespace app = typemerge::app;

constexpr int kN = 24;

// Two touching boxes (labels 1 and 2) in background, or their HU image (bone 1000 in air).
std::vector<double> two_boxes(bool hounsfield) {
  std::vector<double> v(std::size_t(kN) * kN * kN, hounsfield ? -1000.0 : 0.0);
  for (int k = 4; k < 20; ++k)
    for (int j = 4; j < 20; ++j)
      for (int i = 4; i < 20; ++i) {
        const double label = i < 12 ? 1 : 2;
        v[std::size_t(i + kN * (j + kN * k))] = hounsfield ? 1000.0 : label;
      }
  return v;
}

test::NiftiSpec nifti_of(const std::vector<double>& values, int datatype) {
  test::NiftiSpec spec;
  spec.dim = {3, kN, kN, kN, 1, 1, 1, 1};
  spec.datatype = datatype;
  spec.values = values;
  spec.srow = {{{0.9, 0, 0, -10}, {0, 0.9, 0, 10}, {0, 0, 1.1, 40}}};
  spec.descrip = "Doe John 20190412";  // dcm2niix writes acquisition times here
  return spec;
}

void write_seg_nrrd(const fs::path& file) {
  const auto values = two_boxes(false);
  std::vector<std::uint8_t> bytes(values.begin(), values.end());
  test::write_bytes(file,
                    test::nrrd_bytes("type: uchar\ndimension: 3\nsizes: 24 24 24\n"
                                     "space: left-posterior-superior\n"
                                     "space directions: (1,0,0) (0,1,0) (0,0,1)\n"
                                     "space origin: (0,0,0)\nencoding: gzip\n"
                                     "Segment0_Name:=left\nSegment0_Color:=1 0 0\n"
                                     "Segment0_LabelValue:=1\nSegment0_Layer:=0\n"
                                     "Segment1_Name:=right\nSegment1_Color:=0 0 1\n"
                                     "Segment1_LabelValue:=2\nSegment1_Layer:=0\n",
                                     bytes, true),
                    false);
}

// The shared data's 3-slice CT and the liver SEG made on it, or "" when absent.
fs::path shared_seg_data() {
  const char* env = std::getenv("TYPEMERGE_DATA");
  const fs::path data = env != nullptr && *env != '\0' ? fs::path(env) : fs::path(TYPEMERGE_DEFAULT_DATA);
  const fs::path dcmqi = data / "seg" / "dcmqi";
  std::error_code error;
  if (!fs::is_regular_file(dcmqi / "liver.dcm", error) || !fs::is_directory(dcmqi / "ct-3slice", error)) {
    return {};
  }
  return dcmqi;
}

struct Tree {
  fs::path root;
  bool with_seg = false;
};

const Tree& tree() {
  static const Tree made = [] {
    Tree t;
    t.root = fresh_dir("batch_inputs_tree") / "root";
    const fs::path& root = t.root;
    for (const char* folder : {"Doe_John", "p03", "p04", "p05"}) fs::create_directories(root / folder);
    test::write_test_series(root / "Doe_John" / "ct", "P1", {"s1", "ct", "STANDARD", 12, 1.0, 5.0});
    test::write_nifti(root / "Doe_John" / "labels.nii.gz", nifti_of(two_boxes(false), test::kDtUint8));
    test::write_nifti(root / "p03" / "CT_ABD_20190412093012_3.nii.gz",
                      nifti_of(two_boxes(true), test::kDtInt16));
    write_seg_nrrd(root / "p04" / "organs.seg.nrrd");
    const fs::path zipped = root.parent_path() / "zipped";
    test::write_test_series(zipped, "Z1", {"z1", "zipped", "STANDARD", 10, 1.0, 5.0});
    test::write_zip(root / "p05" / "study.zip", test::folder_entries(zipped, "Doe_John/"));
    if (const fs::path dcmqi = shared_seg_data(); !dcmqi.empty()) {
      fs::create_directories(root / "shared" / "ct");
      for (const auto& entry : fs::directory_iterator(dcmqi / "ct-3slice")) {
        fs::copy_file(entry.path(), root / "shared" / "ct" / entry.path().filename());
      }
      fs::copy_file(dcmqi / "liver.dcm", root / "shared" / "ct" / "liver.dcm");
      t.with_seg = true;
    }
    return t;
  }();
  return made;
}

const json* result_named(const json& summary, const std::string& output) {
  for (const auto& r : summary["results"]) {
    if (r.value("output", "") == output) return &r;
  }
  return nullptr;
}

std::string results_text(const json& summary) { return summary["results"].dump(1); }

TEST(BatchInputNames, DigitRunsOfDatesTimesAndIdsAreMasked) {
  EXPECT_EQ(app::without_digit_runs("CT_ABD_20190412093012_3"), "CT_ABD_N_3");
  EXPECT_EQ(app::without_digit_runs("scan_2021-03-14_10:42:05"), "scan_N");
  EXPECT_EQ(app::without_digit_runs("CT_2021.03.14_s2"), "CT_N_s2");
  EXPECT_EQ(app::without_digit_runs("2021-03-14"), "N");
  EXPECT_EQ(app::without_digit_runs("id1234567"), "idN");
  EXPECT_EQ(app::without_digit_runs("T1_3D_12345"), "T1_3D_12345");  // 5 digits: kept
  EXPECT_EQ(app::without_digit_runs("liver"), "liver");
}

TEST(BatchInputNames, FileKindsByNameAndContent) {
  const fs::path dir = fresh_dir("batch_inputs_kinds");
  std::ofstream(dir / "notes.txt") << "notes\n";
  test::write_zip(dir / "a.bin", {{"x.dcm", "x"}});
  EXPECT_EQ(app::file_study_source(dir / "x.NII.GZ"), app::StudySource::nifti);
  EXPECT_EQ(app::file_study_source(dir / "x.nhdr"), app::StudySource::nrrd);
  EXPECT_EQ(app::file_study_source(dir / "a.bin"), app::StudySource::zip);
  EXPECT_EQ(app::file_study_source(dir / "notes.txt"), std::nullopt);
  fs::remove_all(dir);
}

TEST(BatchInputs, EveryKindIsAStudyAccountedNamedWithoutPatientDataAndUpToDateOnRerun) {
  const Tree& t = tree();
  if (!t.with_seg) {
    std::printf("note: the shared DICOM SEG (seg/dcmqi/liver.dcm) not found (TYPEMERGE_DATA): "
                "the tree has no SEG beside its CT series\n");
  }
  const fs::path out = fresh_dir("batch_inputs_out") / "out";
  const std::string command =
      "batch " + t.root.string() + " --preset bone --labels all --out " + out.string();
  const auto run = run_cli(command);
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const json summary = summary_of(out / "summary.json");
  const std::size_t studies = t.with_seg ? 7 : 5;
  EXPECT_EQ(summary["studies"], studies) << results_text(summary);
  EXPECT_EQ(summary["converted"], studies) << results_text(summary);
  EXPECT_EQ(summary["failed"], 0);

  // No name, summary entry or message shows the patient's name, the acquisition time or the
  // ZIP's entry names.
  const std::string everything = results_text(summary) + run.out + run.err;
  for (const char* secret : {"Doe", "John", "DOE", "20190412", "093012"}) {
    EXPECT_EQ(everything.find(secret), std::string::npos) << secret << " in\n" << everything;
  }
  for (const auto& [path, bytes] : outputs_of(out)) {
    EXPECT_EQ(path.find("Doe"), std::string::npos) << path;
    EXPECT_EQ(path.find("2019"), std::string::npos) << path;
  }

  // The grey NIfTI: named after its protocol with the time masked, converted with the preset.
  const json* grey = result_named(summary, "p03/CT_ABD_N_3");
  ASSERT_NE(grey, nullptr) << results_text(summary);
  EXPECT_EQ((*grey)["series"], "nifti");
  ASSERT_EQ((*grey)["surfaces"].size(), 1u);
  EXPECT_TRUE((*grey)["surfaces"][0]["closed_manifold"].get<bool>());
  EXPECT_TRUE(fs::is_regular_file(out / "p03/CT_ABD_N_3/bone.stl"));

  // The .seg.nrrd: label mode by itself (the batch's --preset does not apply to it).
  const json* seg_nrrd = result_named(summary, "p04/organs");
  ASSERT_NE(seg_nrrd, nullptr);
  EXPECT_EQ((*seg_nrrd)["series"], "seg.nrrd");
  EXPECT_TRUE(fs::is_regular_file(out / "p04/organs/left.stl"));
  EXPECT_TRUE(fs::is_regular_file(out / "p04/organs/right.stl"));

  // The ZIP: the preset's surface of the series inside.
  const json* zip = result_named(summary, "p05/study");
  ASSERT_NE(zip, nullptr);
  EXPECT_EQ((*zip)["series"], "zip");
  EXPECT_TRUE(fs::is_regular_file(out / "p05/study/bone.stl"));

  // The label map in the folder spelling the patient's name: masked, one part per label.
  int label_maps = 0;
  for (const auto& r : summary["results"]) {
    if (r["series"] != "nifti" || r["output"] == "p03/CT_ABD_N_3") continue;
    ++label_maps;
    const std::string name = r["output"];
    EXPECT_EQ(name.rfind("study-", 0), 0u) << name;
    EXPECT_EQ(r["surfaces"].size(), 2u);
    EXPECT_TRUE(fs::is_regular_file(out / name / "label-1.stl"));
    EXPECT_TRUE(fs::is_regular_file(out / name / "label-2.stl"));
  }
  EXPECT_EQ(label_maps, 1);

  if (t.with_seg) {
    // The SEG beside its CT series: a study of its own in label mode, as the series is.
    int segs = 0, dicom = 0;
    for (const auto& r : summary["results"]) {
      const std::string name = r["output"];
      if (name.rfind("shared/ct", 0) != 0) continue;
      if (r["series"] == "seg") {
        ++segs;
        EXPECT_EQ(r["status"], "converted");
        EXPECT_GE(r["surfaces"].size(), 1u);
      } else {
        ++dicom;
      }
    }
    EXPECT_EQ(segs, 1);
    EXPECT_EQ(dicom, 1);
  }

  // A rerun changes nothing and converts nothing.
  const auto before = outputs_of(out);
  const auto rerun = run_cli(command);
  ASSERT_EQ(rerun.exit_code, 0) << rerun.err;
  const json again = summary_of(out / "summary.json");
  EXPECT_EQ(again["up_to_date"], studies) << results_text(again);
  EXPECT_EQ(again["converted"], 0);
  EXPECT_EQ(outputs_of(out), before);
}

TEST(BatchInputs, RootMayBeOneFile) {
  const fs::path out = fresh_dir("batch_inputs_one_file") / "out";
  const auto run = run_cli("batch " + (tree().root / "p04" / "organs.seg.nrrd").string() +
                           " --labels all --out " + out.string());
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const json summary = summary_of(out / "summary.json");
  EXPECT_EQ(summary["converted"], 1) << results_text(summary);
  EXPECT_TRUE(fs::is_regular_file(out / "organs" / "left.stl"));
}

TEST(BatchInputs, OptionsThatDoNotApplyRefuseThatStudyOnly) {
  const Tree& t = tree();
  const fs::path out = fresh_dir("batch_inputs_refused") / "out";
  // Without --labels the label map is read as a grey volume, and bone (HU) does not apply.
  const auto run = run_cli("batch " + t.root.string() + " --preset bone --out " + out.string());
  EXPECT_EQ(run.exit_code, 5) << run.out << run.err;
  const json summary = summary_of(out / "summary.json");
  EXPECT_EQ(summary["failed"], 1) << results_text(summary);
  for (const auto& r : summary["results"]) {
    if (r["status"] != "failed") continue;
    EXPECT_EQ(r["series"], "nifti");
    const std::string reason = r["reason"];
    EXPECT_FALSE(reason.empty());
    EXPECT_EQ(reason.find("Doe"), std::string::npos) << reason;
    std::printf("  refused: %s\n", reason.c_str());
  }

  // --hollow does not apply in label mode: the segmentations are refused with the reason,
  // the rest converts.
  const fs::path out2 = fresh_dir("batch_inputs_hollow") / "out";
  const auto hollow = run_cli("batch " + t.root.string() + " --preset bone --hollow 1 --out " +
                              out2.string());
  EXPECT_EQ(hollow.exit_code, 5) << hollow.err;
  const json s2 = summary_of(out2 / "summary.json");
  for (const auto& r : s2["results"]) {
    if (r["series"] == "seg.nrrd" || r["series"] == "seg") {
      EXPECT_EQ(r["status"], "failed");
      EXPECT_NE(r["reason"].get<std::string>().find("label mode"), std::string::npos)
          << r["reason"];
    }
  }
  EXPECT_GE(s2["converted"].get<int>(), 3) << results_text(s2);

  // --labels alone: nothing was asked of the DICOM series (folders and ZIPs), which fail with
  // convert's reason; the segmentations and the label map convert.
  const fs::path out3 = fresh_dir("batch_inputs_labels_only") / "out";
  const auto labels = run_cli("batch " + t.root.string() + " --labels all --out " + out3.string());
  EXPECT_EQ(labels.exit_code, 5) << labels.err;
  const json s3 = summary_of(out3 / "summary.json");
  for (const auto& r : s3["results"]) {
    const std::string series = r["series"];
    const bool labelled = series == "seg.nrrd" || series == "seg" ||
                          (series == "nifti" && r["output"] != "p03/CT_ABD_N_3");
    EXPECT_EQ(r["status"], labelled ? "converted" : "failed") << r.dump();
    if (!labelled) {
      EXPECT_NE(r["reason"].get<std::string>().find("say what to extract"), std::string::npos)
          << r.dump();
    }
  }
}

}  // namespace
