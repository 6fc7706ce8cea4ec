// sample_series: the committed files are exactly what make_sample_series writes, and the
// phantom in them has the values its description promises at known points.
#include <dcmtk/config/osconfig.h>  // must come before any other DCMTK header
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kSampleDir = TYPEMERGE_SAMPLE_SERIES_DIR;
const fs::path kGenerator = TYPEMERGE_MAKE_SAMPLE_SERIES;

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::string> dcm_names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".dcm") names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Runs the generator and returns its exit code (−1 if it did not exit normally).
int run_generator(const std::string& arguments) {
  const std::string command = "'" + kGenerator.string() + "' " + arguments + " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(fs::temp_directory_path() / ("typemerge_sample_series_test_" + name)) {
    fs::remove_all(path_);
  }
  ~ScratchDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

TEST(SampleSeries, GeneratorReproducesTheCommittedFilesByteForByte) {
  const std::vector<std::string> committed = dcm_names(kSampleDir);
  ASSERT_EQ(committed.size(), 60u) << "sample_series/ should hold the 60 generated slices";

  ScratchDir out("regenerated");
  ASSERT_EQ(run_generator("'" + out.path().string() + "' --seed 1"), 0);
  ASSERT_EQ(dcm_names(out.path()), committed);
  for (const std::string& name : committed) {
    EXPECT_TRUE(read_file(out.path() / name) == read_file(kSampleDir / name))
        << name << " differs from the committed file: was sample_series regenerated with "
        << "a changed generator? See sample_series/README.md.";
  }
}

TEST(SampleSeries, AnotherSeedGivesAnotherSeries) {
  ScratchDir out("seed2");
  ASSERT_EQ(run_generator("'" + out.path().string() + "' --seed 2"), 0);
  const std::vector<std::string> names = dcm_names(out.path());
  ASSERT_EQ(names.size(), 60u);
  EXPECT_NE(names, dcm_names(kSampleDir));
}

TEST(SampleSeries, GeneratorRejectsBadCommandLines) {
  EXPECT_EQ(run_generator(""), 2);
  EXPECT_EQ(run_generator("--seed"), 2);
  EXPECT_EQ(run_generator("/tmp/x --seed minus-one"), 2);
  EXPECT_EQ(run_generator("/tmp/x --colour red"), 2);
  EXPECT_EQ(run_generator("--help"), 0);

  // Another series' files in OUTDIR: refuse rather than mix two series in one folder.
  ScratchDir out("mixed");
  fs::create_directories(out.path());
  std::ofstream(out.path() / "IM_other.dcm") << "not ours";
  EXPECT_EQ(run_generator("'" + out.path().string() + "'"), 1);
}

// The committed series as a volume in HU, indexed the DICOM way and placed by its headers.
class SamplePhantom : public ::testing::Test {
 protected:
  struct Slice {
    double z = 0;
    std::string instance_number;
    std::vector<double> hu;
  };

  static void SetUpTestSuite() {
    slices_.clear();
    for (const std::string& name : dcm_names(kSampleDir)) {
      DcmFileFormat file;
      ASSERT_TRUE(file.loadFile((kSampleDir / name).c_str()).good()) << name;
      DcmDataset& ds = *file.getDataset();
      OFString text;
      Slice slice;
      ASSERT_TRUE(ds.findAndGetOFString(DCM_ImagePositionPatient, text, 0).good());
      EXPECT_EQ(std::stod(text.c_str()), kOriginX) << name;
      ASSERT_TRUE(ds.findAndGetOFString(DCM_ImagePositionPatient, text, 1).good());
      EXPECT_EQ(std::stod(text.c_str()), kOriginY) << name;
      ASSERT_TRUE(ds.findAndGetOFString(DCM_ImagePositionPatient, text, 2).good());
      slice.z = std::stod(text.c_str());
      ASSERT_TRUE(ds.findAndGetOFStringArray(DCM_ImageOrientationPatient, text).good());
      EXPECT_EQ(text, "1\\0\\0\\0\\1\\0") << name;
      ASSERT_TRUE(ds.findAndGetOFStringArray(DCM_PixelSpacing, text).good());
      EXPECT_EQ(text, "1.5\\1.5") << name;
      ASSERT_TRUE(ds.findAndGetOFStringArray(DCM_SliceThickness, text).good());
      EXPECT_EQ(text, "2.5") << name;
      ASSERT_TRUE(ds.findAndGetOFStringArray(DCM_PatientName, text).good());
      EXPECT_EQ(text, "Phantom^Sample") << name;
      ASSERT_TRUE(ds.findAndGetOFStringArray(DCM_InstanceNumber, text).good());
      slice.instance_number = text.c_str();
      Uint16 rows = 0, columns = 0, bits_stored = 0;
      ASSERT_TRUE(ds.findAndGetUint16(DCM_Rows, rows).good());
      ASSERT_TRUE(ds.findAndGetUint16(DCM_Columns, columns).good());
      ASSERT_TRUE(ds.findAndGetUint16(DCM_BitsStored, bits_stored).good());
      EXPECT_EQ(rows, kSize);
      EXPECT_EQ(columns, kSize);
      EXPECT_EQ(bits_stored, 12);
      Float64 intercept = 0, slope = 0;
      ASSERT_TRUE(ds.findAndGetFloat64(DCM_RescaleIntercept, intercept).good());
      ASSERT_TRUE(ds.findAndGetFloat64(DCM_RescaleSlope, slope).good());
      EXPECT_EQ(intercept, -1024);
      EXPECT_EQ(slope, 1);
      const Uint16* stored = nullptr;
      unsigned long count = 0;
      ASSERT_TRUE(ds.findAndGetUint16Array(DCM_PixelData, stored, &count).good());
      ASSERT_EQ(count, std::size_t{kSize} * kSize);
      for (unsigned long n = 0; n < count; ++n) {
        ASSERT_LE(stored[n], 4095) << "a stored value above 12 bits in " << name;
        slice.hu.push_back(stored[n] * slope + intercept);
      }
      slices_.push_back(std::move(slice));
    }
    std::sort(slices_.begin(), slices_.end(),
              [](const Slice& a, const Slice& b) { return a.z < b.z; });
  }

  // Mean HU of the (2r+1)² voxels of the slice nearest to z around the voxel nearest (x, y).
  static double mean_hu(double x, double y, double z, int r = 1) {
    const auto nearest = std::min_element(
        slices_.begin(), slices_.end(),
        [z](const Slice& a, const Slice& b) { return std::abs(a.z - z) < std::abs(b.z - z); });
    EXPECT_LT(std::abs(nearest->z - z), 0.01) << "no slice at z = " << z;
    const int i0 = static_cast<int>(std::lround((x - kOriginX) / kPixel));
    const int j0 = static_cast<int>(std::lround((y - kOriginY) / kPixel));
    double sum = 0;
    int count = 0;
    for (int j = j0 - r; j <= j0 + r; ++j) {
      for (int i = i0 - r; i <= i0 + r; ++i) {
        sum += nearest->hu[static_cast<std::size_t>(i + kSize * j)];
        ++count;
      }
    }
    return sum / count;
  }

  static constexpr int kSize = 128;
  static constexpr double kPixel = 1.5;
  static constexpr double kOriginX = -95.25;
  static constexpr double kOriginY = -95.25;
  static inline std::vector<Slice> slices_;
};

TEST_F(SamplePhantom, SlicesAreARegularStackInNonSortingFiles) {
  ASSERT_EQ(slices_.size(), 60u);
  for (std::size_t k = 0; k < slices_.size(); ++k) {
    EXPECT_DOUBLE_EQ(slices_[k].z, -85.0 + 2.5 * static_cast<double>(k));
    EXPECT_EQ(slices_[k].instance_number, std::to_string(k + 1));
  }
  // Sorting by file name must not give slice order (loaders have to sort by position).
  const std::vector<std::string> names = dcm_names(kSampleDir);
  std::vector<int> instance_by_name;
  for (const std::string& name : names) {
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile((kSampleDir / name).c_str()).good());
    Sint32 instance = 0;
    ASSERT_TRUE(file.getDataset()->findAndGetSint32(DCM_InstanceNumber, instance).good());
    instance_by_name.push_back(instance);
  }
  EXPECT_FALSE(std::is_sorted(instance_by_name.begin(), instance_by_name.end()));
  EXPECT_FALSE(std::is_sorted(instance_by_name.rbegin(), instance_by_name.rend()));
}

// Points and values from the phantom's description in tools/make_sample_series.cpp; the head
// centre is (0, 4, −22), skin semi-axes (72, 88, 75). 3 × 3 means bring the noise (σ 18 HU)
// down to σ 6; single voxels get wider bounds.
TEST_F(SamplePhantom, AirOutsideAndAboveTheHead) {
  EXPECT_NEAR(mean_hu(-85, -85, 0), -1000, 20);
  EXPECT_NEAR(mean_hu(85, 85, -50), -1000, 20);
  EXPECT_NEAR(mean_hu(0, 4, 60), -1000, 20);  // above the vertex (z 53)
}

TEST_F(SamplePhantom, SkullShellAlongTheLeftRightAxis) {
  // At the head centre's height the shells cross x at 72 − depth: outer table x ∈ (62.5, 65],
  // diploe (59.5, 62.5], fat (67, 70]. Voxel centres 63.75, 60.75, 68.25 sit inside those.
  for (const double side : {-1.0, 1.0}) {
    EXPECT_NEAR(mean_hu(side * 63.75, 3.75, -22.5, 0), 1400, 90) << "outer table, side " << side;
    EXPECT_NEAR(mean_hu(side * 60.75, 3.75, -22.5, 0), 450, 90) << "diploe, side " << side;
    EXPECT_NEAR(mean_hu(side * 68.25, 3.75, -22.5, 0), -90, 90) << "fat, side " << side;
  }
  EXPECT_NEAR(mean_hu(-80, 3.75, -22.5), -1000, 20);  // just outside the skin
}

TEST_F(SamplePhantom, SoftTissueInside) {
  EXPECT_NEAR(mean_hu(0, 40, 20), 32, 20);     // brain
  EXPECT_NEAR(mean_hu(8.25, 5.25, 0), 8, 20);  // the left lateral ventricle (CSF; +x is left)
}

TEST_F(SamplePhantom, BonePiecesAndAirCavities) {
  EXPECT_NEAR(mean_hu(0.75, 20.25, -60), 700, 20);      // vertebra-sized block
  EXPECT_NEAR(mean_hu(24.75, 24.75, -50, 0), 700, 90);  // styloid-like rod, 4 mm thick
  EXPECT_NEAR(mean_hu(20.25, -29.25, -45), -1000, 20);  // sinus-like cavities
  EXPECT_NEAR(mean_hu(-20.25, -29.25, -45), -1000, 20);
  // Ossicle-sized spheres (r 2.5 mm at (±42, 8, −45)): a few voxels, bone in the middle,
  // brain a centimetre away.
  for (const double side : {-1.0, 1.0}) {
    const double centre = mean_hu(side * 41.25, 8.25, -45, 0) + mean_hu(side * 42.75, 8.25, -45, 0);
    EXPECT_GT(centre / 2, 300) << "ossicle, side " << side;
    EXPECT_NEAR(mean_hu(side * 42, 8, -35), 32, 20) << "brain above the ossicle";
  }
}

}  // namespace
