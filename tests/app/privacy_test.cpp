// Privacy canary (issue 6): a study whose every identifying attribute (PS3.15 Table E.1-1
// style) holds a unique token goes through every command; no token may appear in any output
// file's bytes, any output file's name, stdout or stderr. SeriesDescription is free text
// (scanners and technologists put names in it), so it is hidden unless --show-descriptions.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <zip.h>

#include "app/cli_runner.h"
#include "app/study_tree.h"
#include "ct_writer/ct_writer.h"

namespace {

namespace fs = std::filesystem;
namespace ctw = typemerge::ct_writer;
using typemerge::test::CliRun;
using typemerge::test::fresh_dir;
using typemerge::test::read_file_bytes;
using typemerge::test::run_cli;

struct Canary {
  std::string attribute;
  std::string token;
};

// UIDs may hold only digits and dots, dates and times only digits: those tokens are long
// digit runs that nothing else in the study or the outputs contains.
const std::string kStudyUid = "1.2.826.0.1.3680043.10.1234.7777101";
const std::string kSeriesUid = "1.2.826.0.1.3680043.10.1234.7777202";
const std::string kFrameUid = "1.2.826.0.1.3680043.10.1234.7777303";
const std::string kSopUidPrefix = "1.2.826.0.1.3680043.10.1234.7777404.";

const std::vector<Canary>& canaries() {
  static const std::vector<Canary> list = {
      {"PatientName", "CanaryPatientNameQX"},
      {"PatientID", "CANARYPATIENTIDQX"},
      {"PatientBirthDate", "19421111"},
      {"OtherPatientIDs", "CANARYOTHERIDQX"},
      {"PatientAddress", "CanaryAddressQX"},
      {"PatientAge", "077Y"},
      {"StudyDate", "20110203"},
      {"StudyTime", "101112.131415"},
      {"SeriesDate", "20120304"},
      {"SeriesTime", "111213.141516"},
      {"AcquisitionDate", "20130405"},
      {"AcquisitionTime", "121314.151617"},
      {"ContentDate", "20140506"},
      {"ContentTime", "131415.161718"},
      {"InstanceCreationDate", "20150607"},
      {"InstitutionName", "CanaryInstitutionQX"},
      {"InstitutionAddress", "CanaryInstitutionAddressQX"},
      {"ReferringPhysicianName", "CanaryReferrerQX"},
      {"PerformingPhysicianName", "CanaryPerformerQX"},
      {"OperatorsName", "CanaryOperatorQX"},
      {"StationName", "CANARYSTATIONQX"},
      {"DeviceSerialNumber", "CANARYSERIALQX"},
      {"StudyID", "CANARYSTUDYIDQX"},
      {"AccessionNumber", "CANARYACCESSQX"},
      {"StudyDescription", "CanaryStudyDescriptionQX"},
      {"SeriesDescription", "CanarySeriesDescriptionQX"},
      {"private creator (0009,0010)", "CANARYPRIVCREATORQX"},
      {"private element (0009,1001)", "CANARYPRIVATEVALUEQX"},
      {"StudyInstanceUID", kStudyUid},
      {"SeriesInstanceUID", kSeriesUid},
      {"FrameOfReferenceUID", kFrameUid},
      {"SOPInstanceUID", kSopUidPrefix},
  };
  return list;
}

std::string token(const std::string& attribute) {
  for (const auto& c : canaries()) {
    if (c.attribute == attribute) return c.token;
  }
  return {};
}

// A 24×24×12 head-like study: a ball of bone inside a ball of soft tissue, in air.
fs::path write_canary_study() {
  const fs::path dir = fresh_dir("privacy_study");
  ctw::SeriesLayout layout;
  layout.uid_seed = "privacy";
  layout.columns = 24;
  layout.rows = 24;
  layout.slices = 12;
  layout.slice_spacing = 2.0;
  layout.origin = {-12, -12, 40};
  layout.hu = [](int i, int j, int k) {
    const double d = std::hypot(i - 11.5, j - 11.5, (k - 5.5) * 2);
    return d < 4.5 ? 1200.0 : d < 9 ? 40.0 : -1000.0;
  };
  auto specs = ctw::make_axial_series(layout);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    ctw::CtSliceSpec& s = specs[k];
    s.patient_name = token("PatientName");
    s.patient_id = token("PatientID");
    s.patient_birth_date = token("PatientBirthDate");
    s.study_date = token("StudyDate");
    s.study_time = token("StudyTime");
    s.study_id = token("StudyID");
    s.accession_number = token("AccessionNumber");
    s.referring_physician_name = token("ReferringPhysicianName");
    s.study_description = token("StudyDescription");
    s.series_description = "Head " + token("SeriesDescription");
    s.study_instance_uid = kStudyUid;
    s.series_instance_uid = kSeriesUid;
    s.frame_of_reference_uid = kFrameUid;
    s.sop_instance_uid = kSopUidPrefix + std::to_string(k + 1);
    s.extra = {
        {{0x0010, 0x1000}, token("OtherPatientIDs")},
        {{0x0010, 0x1040}, token("PatientAddress")},
        {{0x0010, 0x1010}, token("PatientAge")},
        {{0x0008, 0x0021}, token("SeriesDate")},
        {{0x0008, 0x0031}, token("SeriesTime")},
        {{0x0008, 0x0022}, token("AcquisitionDate")},
        {{0x0008, 0x0032}, token("AcquisitionTime")},
        {{0x0008, 0x0023}, token("ContentDate")},
        {{0x0008, 0x0033}, token("ContentTime")},
        {{0x0008, 0x0012}, token("InstanceCreationDate")},
        {{0x0008, 0x0080}, token("InstitutionName")},
        {{0x0008, 0x0081}, token("InstitutionAddress")},
        {{0x0008, 0x1050}, token("PerformingPhysicianName")},
        {{0x0008, 0x1070}, token("OperatorsName")},
        {{0x0008, 0x1010}, token("StationName")},
        {{0x0018, 0x1000}, token("DeviceSerialNumber")},
        {{0x0009, 0x0010}, token("private creator (0009,0010)")},
        {{0x0009, 0x1001}, token("private element (0009,1001)")},
    };
    ctw::write_ct_slice(s, dir / ("image" + std::to_string(k) + ".dcm"));
  }
  return dir;
}

// Every token found in `bytes`, as "attribute in what".
std::vector<std::string> leaks(const std::string& bytes, const std::string& what) {
  std::vector<std::string> found;
  for (const auto& c : canaries()) {
    if (bytes.find(c.token) != std::string::npos) found.push_back(c.attribute + " in " + what);
  }
  return found;
}

// What a file says: its bytes, and for a 3MF package (a zip of deflated parts, where a token
// would not show in the raw bytes) also every part inflated and its name.
std::string readable_content(const fs::path& file) {
  std::string content = read_file_bytes(file);
  if (file.extension() != ".3mf") return content;
  int error = 0;
  zip_t* archive = zip_open(file.c_str(), ZIP_RDONLY, &error);
  if (archive == nullptr) {
    ADD_FAILURE() << "not a zip package: " << file;
    return content;
  }
  const zip_int64_t entries = zip_get_num_entries(archive, 0);
  EXPECT_GE(entries, 3) << file;
  for (zip_int64_t e = 0; e < entries; ++e) {
    zip_stat_t stat;
    if (zip_stat_index(archive, e, 0, &stat) != 0) continue;
    content += std::string("\n") + stat.name + "\n";
    std::string part(stat.size, '\0');
    zip_file_t* opened = zip_fopen_index(archive, e, 0);
    EXPECT_NE(opened, nullptr) << stat.name;
    if (opened == nullptr) continue;
    EXPECT_EQ(zip_fread(opened, part.data(), stat.size), zip_int64_t(stat.size)) << stat.name;
    zip_fclose(opened);
    content += part;
  }
  zip_close(archive);
  return content;
}

TEST(Privacy, TheCanaryStudyHoldsEveryToken) {
  // The check below is only as good as the input: every token must be in the files.
  const fs::path dir = write_canary_study();
  const std::string file = read_file_bytes(dir / "image0.dcm");
  for (const auto& c : canaries()) {
    EXPECT_NE(file.find(c.token), std::string::npos) << c.attribute << " was not written";
  }
}

TEST(Privacy, NoIdentifyingAttributeReachesAnyOutput) {
  const fs::path study = write_canary_study();
  const fs::path out = fresh_dir("privacy_out");
  const std::string in = study.string();
  // The batch input: the study in a folder named by the patient's ID, as archive exports do.
  const fs::path batch_root = fresh_dir("privacy_batch_root");
  fs::copy(study, batch_root / ("site_" + token("PatientID")), fs::copy_options::recursive);
  // Folders no study comes of, named after the patient too, with nothing to compare the names
  // with: cut-off copies of the study's slices (every token in their headers) beside a note,
  // and a folder of notes. The batch lists them by hash only.
  const fs::path damaged = batch_root / ("copy_" + token("PatientName"));
  for (int k = 0; k < 3; ++k) {
    const std::string name = "image" + std::to_string(k) + ".dcm";
    typemerge::test::write_truncated_copy(study / name, damaged / name);
  }
  { std::ofstream(damaged / (token("AccessionNumber") + ".txt")) << token("PatientID") << "\n"; }
  fs::create_directories(batch_root / token("PatientBirthDate"));
  std::ofstream(batch_root / token("PatientBirthDate") / "notes.txt") << token("StudyID") << "\n";
  const std::vector<std::string> commands = {
      "info " + in,
      "info --json " + in,
      "info --list-skipped " + in,
      "volume " + in + " -o " + (out / "volume.nrrd").string(),
      "volume " + in + " --float -o " + (out / "volume_float.nrrd").string(),
      "convert " + in + " --preset bone,skin -o " + (out / "surfaces").string() + " --preview " +
          "--report " + (out / "report.json").string(),
      "convert " + in + " --iso 300 --ascii -o " + (out / "ascii.stl").string(),
      "convert " + in + " --iso auto --hollow 2 --allow-non-ct -o " + (out / "hollow.stl").string() +
          " --report " + (out / "hollow.json").string(),
      "convert " + in + " --iso 300 -o " + (out / "mesh.ply").string(),
      "convert " + in + " --iso 300 -o " + (out / "mesh.obj").string(),
      "convert " + in + " --preset bone,skin -o " + (out / "surfaces.3mf").string(),
      "batch " + batch_root.string() + " --preset bone,skin --preview --out " +
          (out / "batch").string() + " --log " + (out / "batch.jsonl").string(),
      "batch " + batch_root.string() + " --preset bone,skin --format 3mf --out " +
          (out / "batch_3mf").string(),
      "stats " + (out / "surfaces" / "bone.stl").string(),
      "stats --json " + (out / "surfaces" / "skin.stl").string(),
  };
  std::vector<std::string> found;
  for (const std::string& command : commands) {
    const CliRun r = run_cli(command);
    // batch: the damaged copies fail it (some failed, 5).
    EXPECT_EQ(r.exit_code, command.rfind("batch", 0) == 0 ? 5 : 0) << command << "\n" << r.out
                                                                   << r.err;
    for (auto& l : leaks(r.out, "stdout of `" + command + "`")) found.push_back(l);
    for (auto& l : leaks(r.err, "stderr of `" + command + "`")) found.push_back(l);
  }
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    const std::string name = entry.path().lexically_relative(out).string();
    for (auto& l : leaks(name, "the name " + name)) found.push_back(l);
    if (!entry.is_regular_file()) continue;
    ++files;
    for (auto& l : leaks(readable_content(entry.path()), name)) found.push_back(l);
  }
  // nrrd ×2, bone and skin STL + PNG, report, ASCII STL, hollow STL + report, PLY, OBJ, the
  // bone+skin 3MF; batch:
  // bone and skin STL + PNG, summary JSON + CSV, the study's manifest record, the event log;
  // batch --format 3mf: the study's package, summary JSON + CSV, the manifest record.
  EXPECT_EQ(files, 25u);
  // The check covers the folder entries only if they are there.
  const std::string summary = read_file_bytes(out / "batch" / "summary.json");
  EXPECT_NE(summary.find("\"status\": \"no_study\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"status\": \"no_ct\""), std::string::npos) << summary;
  for (const std::string& l : found) ADD_FAILURE() << "leak: " << l;
}

TEST(Privacy, SeriesDescriptionOnlyWhenAskedFor) {
  // The positive control of the canary test: the token is found when it is really printed.
  const fs::path study = write_canary_study();
  const fs::path out = fresh_dir("privacy_described");
  const std::string description = token("SeriesDescription");
  const CliRun text = run_cli("info --show-descriptions " + study.string());
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("\"Head " + description + "\""), std::string::npos) << text.out;
  const CliRun json = run_cli("info --json --show-descriptions " + study.string());
  EXPECT_NE(json.out.find("\"description\": \"Head " + description + "\""), std::string::npos)
      << json.out;
  const fs::path report = out / "report.json";
  ASSERT_EQ(run_cli("convert " + study.string() + " --iso 300 --show-descriptions -o " +
                    (out / "s.stl").string() + " --report " + report.string())
                .exit_code,
            0);
  EXPECT_NE(read_file_bytes(report).find(description), std::string::npos);
  // Only the description: nothing else comes with it.
  for (const auto& c : canaries()) {
    if (c.attribute == "SeriesDescription") continue;
    EXPECT_EQ(text.out.find(c.token), std::string::npos) << c.attribute;
    EXPECT_EQ(json.out.find(c.token), std::string::npos) << c.attribute;
  }
}

}  // namespace
