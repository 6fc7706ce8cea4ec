// NIfTI and NRRD files whose values are integers within int16 load as int16 samples
// (nifti_reader.h, nrrd_reader.h): converting one gives, byte for byte, the files that the
// same values stored as floats give — grey surfaces (tm, --hollow, --denoise, --voxel-size)
// and label maps (--labels).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "app/cli_runner.h"
#include "app/input_options.h"
#include "app/volume_file_input.h"
#include "nifti/nifti_reader.h"
#include "nrrd/nrrd_reader.h"
#include "support/scratch_files.h"
#include "support/volume_file_writers.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using test::run_cli;

constexpr int kN = 36;

// A CT-like scene, x fastest: a bone-like shell (values falling off with the distance from
// its middle radius, so that crossings interpolate) in soft tissue, in air at the border.
std::vector<double> grey_scene() {
  std::vector<double> v;
  for (int k = 0; k < kN; ++k) {
    for (int j = 0; j < kN; ++j) {
      for (int i = 0; i < kN; ++i) {
        const double r = std::hypot(i - 17.5, j - 18.0, k - 16.5);
        double value = r < 15 ? 40.0 : -1000.0;
        if (std::abs(r - 9) < 4) value = std::round(1400 - 300 * std::abs(r - 9));
        v.push_back(value);
      }
    }
  }
  return v;
}

test::NiftiSpec nifti(int datatype, const std::vector<double>& values) {
  test::NiftiSpec spec;
  spec.dim = {3, kN, kN, kN, 1, 1, 1, 1};
  spec.datatype = datatype;
  spec.values = values;
  spec.srow = {{{0.8, 0, 0, -14}, {0, 0.8, 0, 9}, {0, 0, 1.1, 40}}};
  return spec;
}

// int16.nrrd and float.nrrd in `dir`: the same values as shorts and as floats, gzip-encoded or
// raw, on the NIfTI files' grid.
void write_nrrd_pair(const fs::path& dir, const std::vector<double>& values, bool gzip) {
  const std::string header = std::string(
                                 "dimension: 3\nsizes: 36 36 36\nspace: left-posterior-superior\n"
                                 "space directions: (0.8,0,0) (0,0.8,0) (0,0,1.1)\n"
                                 "space origin: (14,-9,40)\nendian: little\nencoding: ") +
                             (gzip ? "gzip\n" : "raw\n");
  test::write_bytes(dir / "int16.nrrd",
                    test::nrrd_bytes("type: short\n" + header,
                                     test::raw_samples<std::int16_t>(values), gzip),
                    false);
  test::write_bytes(dir / "float.nrrd",
                    test::nrrd_bytes("type: float\n" + header, test::raw_samples<float>(values),
                                     gzip),
                    false);
}

class VolumeFileInt16Test : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::fresh_dir("int16_files"); }
  void TearDown() override { fs::remove_all(dir_); }

  // `convert INPUT ARGS -o OUTPUT` (output under dir_), its bytes; fails the test on error.
  std::string convert(const fs::path& input, const std::string& args, const std::string& output) {
    const auto run = run_cli("convert " + input.string() + " " + args + " --threads 2 -o " +
                             (dir_ / output).string());
    EXPECT_EQ(run.exit_code, 0) << args << ": " << run.err;
    return test::read_file_bytes(dir_ / output);
  }

  fs::path dir_;
};

TEST_F(VolumeFileInt16Test, GreyNiftiAndNrrdGiveTheFloatFilesBytes) {
  const std::vector<double> values = grey_scene();
  test::write_nifti(dir_ / "int16.nii.gz", nifti(test::kDtInt16, values));
  test::write_nifti(dir_ / "float.nii.gz", nifti(test::kDtFloat32, values));
  write_nrrd_pair(dir_, values, true);
  // The loaders' storage choice.
  EXPECT_TRUE(nifti::read_nifti(dir_ / "int16.nii.gz").volume.holds_int16());
  EXPECT_FALSE(nifti::read_nifti(dir_ / "float.nii.gz").volume.holds_int16());
  EXPECT_TRUE(nrrd::read_nrrd(dir_ / "int16.nrrd").layers.at(0).holds_int16());
  EXPECT_FALSE(nrrd::read_nrrd(dir_ / "float.nrrd").layers.at(0).holds_int16());

  for (const std::string args : {"--preset bone", "--iso 300 --algorithm mc --finish none",
                                 "--preset bone --hollow 2", "--preset bone --denoise median",
                                 "--iso 300 --voxel-size 1.3"}) {
    for (const char* format : {"nii.gz", "nrrd"}) {
      const std::string a = convert(dir_ / ("int16." + std::string(format)), args, "a.stl");
      const std::string b = convert(dir_ / ("float." + std::string(format)), args, "b.stl");
      EXPECT_GT(a.size(), 84u + 50u * 100u) << args;  // a surface, not an empty file
      EXPECT_TRUE(a == b) << format << " " << args << ": int16 and float inputs differ";
    }
  }
}

TEST_F(VolumeFileInt16Test, Uint8LabelMapGivesTheFloatFilesBytes) {
  std::vector<double> labels;
  for (int k = 0; k < kN; ++k) {
    for (int j = 0; j < kN; ++j) {
      for (int i = 0; i < kN; ++i) {
        const double r1 = std::hypot(i - 12.0, j - 18.0, k - 18.0);
        const double r2 = std::hypot(i - 24.0, j - 18.0, k - 18.0);
        labels.push_back(r1 <= 7 ? 1 : r2 <= 6 ? 200 : 0);
      }
    }
  }
  test::NiftiSpec uint8 = nifti(test::kDtUint8, labels), as_float = nifti(test::kDtFloat32, labels);
  uint8.intent_code = as_float.intent_code = 1002;  // NIFTI_INTENT_LABEL
  test::write_nifti(dir_ / "uint8.nii", uint8);
  test::write_nifti(dir_ / "float.nii", as_float);
  EXPECT_TRUE(nifti::read_nifti(dir_ / "uint8.nii").volume.holds_int16());
  for (const char* label : {"1", "200"}) {
    const std::string args = std::string("--labels ") + label;
    const std::string a = convert(dir_ / "uint8.nii", args, "a.stl");
    const std::string b = convert(dir_ / "float.nii", args, "b.stl");
    EXPECT_GT(a.size(), 84u + 50u * 100u) << label;
    EXPECT_TRUE(a == b) << "label " << label << ": uint8 and float inputs differ";
  }
}

// --max-memory and batch schedule a study by its estimate before loading it: a file whose header
// alone shows that it loads as int16 is counted at 2 bytes a voxel, as a DICOM CT series is
// (app/memory_budget.h); where its data decides, or it loads as float, at 4.
TEST_F(VolumeFileInt16Test, TheHeaderTellsTheEstimateWhichFilesLoadAsInt16) {
  const std::vector<double> values = grey_scene();
  struct Case {
    const char* name;
    int datatype;
    double slope;
    double inter;
    bool int16;
  };
  const Case cases[] = {{"int16", test::kDtInt16, 0, 0, true},
                        {"int16_offset", test::kDtInt16, 1, -1024, false},  // the data decides
                        {"uint8", test::kDtUint8, 0, 0, true},
                        {"int32", test::kDtInt32, 0, 0, false},            // the data decides
                        {"int16_scaled", test::kDtInt16, 0.5, 0, false},
                        {"float", test::kDtFloat32, 0, 0, false}};
  for (const Case& c : cases) {
    test::NiftiSpec spec = nifti(c.datatype, values);
    if (c.datatype == test::kDtUint8) {
      for (double& v : spec.values) v = v > 0 ? 200 : 0;
    }
    spec.slope = c.slope;
    spec.inter = c.inter;
    const fs::path path = dir_ / (std::string(c.name) + ".nii");
    test::write_nifti(path, spec);
    EXPECT_EQ(read_volume_file_shape(path, InputKind::nifti).int16_samples, c.int16) << c.name;
    InputOptions options;
    options.input = path.string();
    bool seen = !c.int16;
    const LoadedInput loaded =
        load_input(options, "", [&](const InputShape& shape) { seen = shape.int16_samples; });
    EXPECT_EQ(seen, c.int16) << c.name << ": what convert's estimate is given";
    // Never counted at 2 bytes a voxel when it loads as float.
    if (!loaded.loaded.volume.holds_int16()) EXPECT_FALSE(c.int16) << c.name;
  }
  write_nrrd_pair(dir_, values, false);
  EXPECT_TRUE(read_volume_file_shape(dir_ / "int16.nrrd", InputKind::nrrd).int16_samples);
  EXPECT_FALSE(read_volume_file_shape(dir_ / "float.nrrd", InputKind::nrrd).int16_samples);
}

}  // namespace
}  // namespace typemerge::app
