// A DICOM SEG through the executable: `convert` in label mode by itself (one STL per segment,
// named after it, overlapping segments included), `info` listing its segments; nothing of the
// file's patient or creator attributes in outputs or messages.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>

#include "seg/seg_writer.h"
#include "support/scratch_files.h"

namespace typemerge::seg {
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

// Three segments on 8 slices of 16 x 16: Liver and Tumour overlap (two layers), Bone apart.
test::SynthSeg three_segments() {
  test::SynthSeg spec;
  spec.rows = 16;
  spec.columns = 16;
  spec.pixel_spacing = {1.0, 1.0};
  spec.segments = {{"Liver", std::array<std::uint16_t, 3>{41661, 41167, 40792}},
                   {"Tumour", std::nullopt},
                   {"Bone", std::nullopt}};
  for (int k = 1; k < 7; ++k) {
    spec.frames.push_back({1, {0, 0, 1.0 * k}, test::box_pixels(spec, 2, 9, 2, 9)});
    spec.frames.push_back({2, {0, 0, 1.0 * k}, test::box_pixels(spec, 6, 12, 6, 12)});
    spec.frames.push_back({3, {0, 0, 1.0 * k}, test::box_pixels(spec, 2, 4, 12, 14)});
  }
  return spec;
}

TEST(SegApp, ConvertsEachSegmentToANamedPart) {
  const fs::path dir = test::fresh_dir("seg_app_convert");
  const fs::path input = dir / "input.dcm";
  const test::SynthSeg spec = three_segments();
  test::write_seg(spec, input);
  const fs::path out = dir / "parts";
  const CommandRun result = run("convert " + input.string() + " -o " + out.string());
  ASSERT_EQ(result.exit_code, 0) << result.out;
  for (const char* name : {"Liver", "Tumour", "Bone"}) {
    const fs::path part = out / (std::string(name) + ".stl");
    ASSERT_TRUE(fs::exists(part)) << name << "\n" << result.out;
    EXPECT_GT(fs::file_size(part), 84u) << name;
  }
  std::string everything = result.out;
  for (const auto& item : fs::directory_iterator(out)) {
    everything += item.path().filename().string() + test::read_file_bytes(item.path()).substr(0, 80);
  }
  for (const std::string& secret : {spec.patient_name, spec.patient_id, spec.content_creator}) {
    EXPECT_EQ(everything.find(secret), std::string::npos) << secret;
  }
  fs::remove_all(dir);
}

TEST(SegApp, InfoListsTheSegments) {
  const fs::path dir = test::fresh_dir("seg_app_info");
  const fs::path input = dir / "input.dcm";
  const test::SynthSeg spec = three_segments();
  test::write_seg(spec, input);
  const CommandRun result = run("info " + input.string());
  ASSERT_EQ(result.exit_code, 0) << result.out;
  for (const char* name : {"Liver", "Tumour", "Bone", "DICOM SEG"}) {
    EXPECT_NE(result.out.find(name), std::string::npos) << name << "\n" << result.out;
  }
  EXPECT_EQ(result.out.find(spec.patient_name), std::string::npos);
  fs::remove_all(dir);
}

TEST(SegApp, ABrokenSegIsRefusedWithItsReason) {
  const fs::path dir = test::fresh_dir("seg_app_broken");
  const fs::path input = dir / "input.dcm";
  test::SynthSeg spec = three_segments();
  spec.spacing_between_slices = 1.0;
  spec.frames.push_back({3, {0, 0, 7.5}, test::box_pixels(spec, 2, 4, 12, 14)});
  test::write_seg(spec, input);
  const CommandRun result = run("convert " + input.string() + " -o " + (dir / "out").string());
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.out.find("fit no slice grid"), std::string::npos) << result.out;
  EXPECT_FALSE(fs::exists(dir / "out" / "Liver.stl"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace typemerge::seg
