// make_sample_series: writes the synthetic head CT that ships in sample_series/.
//
//   make_sample_series OUTDIR [--seed N]
//
// The phantom, in patient LPS millimetres (x to the patient's left, y posterior, z superior),
// is a stack of nested ellipsoid shells, centre (0, 4, −22), skin semi-axes (72, 88, 75), each
// shell its own tissue (thickness measured inward, every semi-axis shortened by the depth):
//
//   skin (+45 HU) 2 mm │ fat (−90) 3 mm │ scalp (+40) 2 mm │ outer table (+1400) 2.5 mm │
//   diploe (+450) 3 mm │ inner table (+1200) 1.5 mm │ CSF (+8) 1.5 mm │ brain (+32)
//
// plus two CSF ventricles in the brain, two sinus-like air cavities (−1000) with thin bony walls
// (+500), and small bone pieces of +700 HU: a vertebra-sized block, two ossicle-sized spheres
// (r 2.5 mm: a few voxels, for small-component handling) and a thin styloid-like rod. Each voxel
// averages 3 × 3 × 3 point samples (partial volume, as a scanner's finite voxels give), then gets
// Gaussian noise of σ = 18 HU.
//
// The output is byte-identical for the same seed on every machine: the noise is integer-based
// (Irwin–Hall: the sum of 12 uniform 32-bit draws of std::mt19937, whose sequence the standard
// fixes, unlike std::normal_distribution's), the geometry uses only +, −, ×, ÷ (IEEE-exact, with
// -ffp-contract=off), and ct_writer derives UIDs from the seed and takes no date from the clock.
//
// Stored as CT scanners commonly do: 16 bits allocated, 12 stored, unsigned, intercept −1024,
// slope 1, explicit VR little endian; 128 × 128 × 60 voxels of 1.5 × 1.5 × 2.5 mm.
//
// Exit codes: 0 written (or --help); 1 could not write (message on stderr); 2 bad command line.
#include <algorithm>
#include <array>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <random>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "ct_writer/ct_writer.h"

namespace {

namespace ctw = typemerge::ct_writer;
using Vec3 = ctw::Vec3;

// Grid: 128 × 128 pixels of 1.5 mm (a 192 mm field of view) × 60 slices 2.5 mm apart, centred
// in x and y on the head; z runs from the neck (−85 mm) to above the vertex (+62.5 mm).
constexpr std::uint16_t kColumns = 128;
constexpr std::uint16_t kRows = 128;
constexpr int kSlices = 60;
constexpr double kPixelMm = 1.5;
constexpr double kSliceMm = 2.5;
// Centre of the first voxel; with 128 columns of 1.5 mm the grid is symmetric about x = y = 0.
constexpr Vec3 kOrigin{-95.25, -95.25, -85.0};

constexpr double kAirHu = -1000;
constexpr double kNoiseSigmaHu = 18;
constexpr int kSubsamples = 3;  // per axis, per voxel

struct Ellipsoid {
  Vec3 centre;
  Vec3 semi_axes;

  bool contains(const Vec3& p) const {
    const double x = (p[0] - centre[0]) / semi_axes[0];
    const double y = (p[1] - centre[1]) / semi_axes[1];
    const double z = (p[2] - centre[2]) / semi_axes[2];
    return x * x + y * y + z * z <= 1.0;
  }
  // The same ellipsoid with every semi-axis `mm` shorter: close to an inward offset surface
  // for shells a few millimetres thick, and exact enough for a phantom.
  Ellipsoid shrunk(double mm) const {
    return {centre, {semi_axes[0] - mm, semi_axes[1] - mm, semi_axes[2] - mm}};
  }
};

struct Region {
  Ellipsoid shape;
  double hu;
};

class HeadPhantom {
 public:
  HeadPhantom() {
    // Tissue shells, outermost first: a point takes the value of the innermost shell that
    // contains it. Depths are millimetres in from the skin surface.
    const Ellipsoid skin{{0, 4, -22}, {72, 88, 75}};
    struct Layer {
      double depth_mm;
      double hu;
    };
    constexpr std::array<Layer, 8> kLayers{{
        {0.0, 45},     // skin
        {2.0, -90},    // subcutaneous fat
        {5.0, 40},     // scalp muscle and galea
        {7.0, 1400},   // outer table: dense cortical bone
        {9.5, 450},    // diploe: cancellous bone between the tables
        {12.5, 1200},  // inner table, thinner than the outer
        {14.0, 8},     // CSF
        {15.5, 32},    // brain
    }};
    for (const Layer& layer : kLayers) shells_.push_back({skin.shrunk(layer.depth_mm), layer.hu});

    // Inclusions, tested before the shells in this order (first match wins). All lie in the
    // brain at least 3 mm from the inner skull and from each other, so that every bone piece is
    // its own connected component.
    inclusions_ = {
        {{{0, 20, -60}, {12, 10, 8}}, 700},       // vertebra-sized bone block
        {{{-42, 8, -45}, {2.5, 2.5, 2.5}}, 700},  // ossicle-sized bone spheres
        {{{42, 8, -45}, {2.5, 2.5, 2.5}}, 700},
        {{{25, 25, -50}, {2, 2, 8}}, 700},         // styloid-like rod
        {{{-20, -30, -45}, {9, 10, 10}}, kAirHu},  // sinus-like air cavities...
        {{{20, -30, -45}, {9, 10, 10}}, kAirHu},
        {{{-20, -30, -45}, {10.5, 11.5, 11.5}}, 500},  // ...inside 1.5 mm bony walls
        {{{20, -30, -45}, {10.5, 11.5, 11.5}}, 500},
        {{{-8, 5, 0}, {5, 18, 10}}, 8},  // lateral ventricles (CSF)
        {{{8, 5, 0}, {5, 18, 10}}, 8},
    };
  }

  double hu_at(const Vec3& p) const {
    for (const Region& region : inclusions_) {
      if (region.shape.contains(p)) return region.hu;
    }
    double hu = kAirHu;
    for (const Region& shell : shells_) {
      if (!shell.shape.contains(p)) break;  // nested: outside this one means outside all deeper
      hu = shell.hu;
    }
    return hu;
  }

  // Mean over kSubsamples³ points spread evenly inside the voxel centred at `centre`.
  double voxel_hu(const Vec3& centre) const {
    const Vec3 size{kPixelMm, kPixelMm, kSliceMm};
    double sum = 0;
    for (int c = 0; c < kSubsamples; ++c) {
      for (int b = 0; b < kSubsamples; ++b) {
        for (int a = 0; a < kSubsamples; ++a) {
          const std::array<int, 3> n{a, b, c};
          Vec3 p;
          for (int axis = 0; axis < 3; ++axis) {
            p[axis] = centre[axis] + size[axis] * ((n[axis] + 0.5) / kSubsamples - 0.5);
          }
          sum += hu_at(p);
        }
      }
    }
    return sum / (kSubsamples * kSubsamples * kSubsamples);
  }

 private:
  std::vector<Region> shells_;
  std::vector<Region> inclusions_;
};

// Standard normal deviates, approximately: the Irwin–Hall sum of 12 uniforms has mean 6 and
// variance 1. Integer arithmetic up to one exact conversion, so identical on every platform;
// its tails stop at ±6σ, which CT noise never reaches in a way anyone could see.
class PortableGaussian {
 public:
  explicit PortableGaussian(std::uint32_t seed) : engine_(seed) {}

  double operator()() {
    std::uint64_t sum = 0;
    for (int n = 0; n < 12; ++n) sum += engine_();
    constexpr double kTwoTo32 = 4294967296.0;
    return (static_cast<double>(sum) - 6 * kTwoTo32) / kTwoTo32;
  }

 private:
  std::mt19937 engine_;
};

struct Options {
  std::filesystem::path out_dir;
  std::uint32_t seed = 1;
};

constexpr std::string_view kUsage =
    "usage: make_sample_series OUTDIR [--seed N]\n"
    "Writes the synthetic head CT series (60 slices, 128x128, 1.5 x 1.5 x 2.5 mm) to OUTDIR.\n"
    "The same seed gives byte-identical files. Default seed: 1.\n";

// Returns false (after printing why) when the command line is not usable.
bool parse_args(int argc, char** argv, Options& options) {
  bool have_dir = false;
  for (int n = 1; n < argc; ++n) {
    const std::string_view arg = argv[n];
    if (arg == "--seed" && n + 1 < argc) {
      const std::string_view value = argv[++n];
      const auto [end, error] =
          std::from_chars(value.data(), value.data() + value.size(), options.seed);
      if (error != std::errc() || end != value.data() + value.size()) {
        std::cerr << "make_sample_series: --seed needs a number from 0 to 4294967295, got '"
                  << value << "'\n";
        return false;
      }
    } else if (!arg.empty() && arg[0] == '-') {
      std::cerr << "make_sample_series: unknown option '" << arg << "'\n";
      return false;
    } else if (!have_dir) {
      options.out_dir = arg;
      have_dir = true;
    } else {
      std::cerr << "make_sample_series: more than one OUTDIR\n";
      return false;
    }
  }
  if (!have_dir) std::cerr << "make_sample_series: OUTDIR missing\n";
  return have_dir;
}

// Stored values for every voxel, x fastest, then y, then slice: phantom + noise, in a fixed
// order so the noise sequence is part of the definition of the output.
std::vector<std::int32_t> render(const HeadPhantom& phantom, std::uint32_t seed) {
  PortableGaussian noise(seed);
  std::vector<std::int32_t> stored;
  stored.reserve(std::size_t{kColumns} * kRows * kSlices);
  for (int k = 0; k < kSlices; ++k) {
    for (int j = 0; j < kRows; ++j) {
      for (int i = 0; i < kColumns; ++i) {
        const Vec3 centre{kOrigin[0] + i * kPixelMm, kOrigin[1] + j * kPixelMm,
                          kOrigin[2] + k * kSliceMm};
        const double hu = phantom.voxel_hu(centre) + kNoiseSigmaHu * noise();
        stored.push_back(ctw::stored_from_hu(hu, -1024, 1, 12, 0));
      }
    }
  }
  return stored;
}

std::vector<ctw::CtSliceSpec> make_specs(const std::vector<std::int32_t>& stored,
                                         std::uint32_t seed) {
  ctw::SeriesLayout layout;
  layout.uid_seed = "typemerge/sample_series/seed-" + std::to_string(seed);
  layout.columns = kColumns;
  layout.rows = kRows;
  layout.slices = kSlices;
  layout.pixel_spacing = {kPixelMm, kPixelMm};
  layout.slice_spacing = kSliceMm;
  layout.origin = kOrigin;
  layout.orientation = {1, 0, 0, 0, 1, 0};
  layout.bits_allocated = 16;
  layout.bits_stored = 12;
  layout.high_bit = 11;
  layout.pixel_representation = 0;
  layout.rescale_intercept = -1024;
  layout.rescale_slope = 1;
  layout.stored_value = [&stored](int i, int j, int k) {
    return stored[static_cast<std::size_t>(i + kColumns * (j + kRows * k))];
  };
  layout.series_description = "Synthetic head phantom";
  layout.series_number = 2;
  layout.transfer_syntax = ctw::TransferSyntax::explicit_little;

  std::vector<ctw::CtSliceSpec> specs = ctw::make_axial_series(layout);
  // std::string values (not char pointers): GCC 12 at -O3 raises a false -Wrestrict on
  // string assignment from a literal here (GCC bug 105329).
  using namespace std::string_literals;
  for (ctw::CtSliceSpec& spec : specs) {
    spec.patient_name = "Phantom^Sample"s;
    spec.patient_id = "SAMPLE"s;
    spec.patient_birth_date = ""s;  // type 2: present, empty — there is no patient
    spec.patient_sex = "O"s;
    spec.study_date = "20000101"s;  // fixed and obviously not a real acquisition date
    spec.study_time = "000000"s;
    spec.study_description = "typemerge sample series"s;
    spec.manufacturer = "typemerge make_sample_series"s;
    spec.convolution_kernel = "STANDARD"s;
    spec.rescale_type = "HU"s;
    spec.window_center = "40"s;
    spec.window_width = "400"s;
  }
  return specs;
}

// Names that do not sort in slice order, as scanners' often don't: a hash of seed and index.
// FNV-1a alone leaves similar keys with similar hashes; the splitmix64 finaliser spreads them.
std::string file_name(std::uint32_t seed, std::size_t index) {
  std::uint64_t h = ctw::fnv1a64("typemerge/sample_series/seed-" + std::to_string(seed) + "/file-" +
                                 std::to_string(index));
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  h ^= h >> 31;
  char name[32];
  std::snprintf(name, sizeof name, "IM_%08x.dcm", static_cast<unsigned>(h & 0xFFFFFFFFu));
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  for (int n = 1; n < argc; ++n) {
    if (std::string_view(argv[n]) == "--help" || std::string_view(argv[n]) == "-h") {
      std::cout << kUsage;
      return 0;
    }
  }
  Options options;
  if (!parse_args(argc, argv, options)) {
    std::cerr << kUsage;
    return 2;
  }
  try {
    std::vector<std::string> names;
    for (int k = 0; k < kSlices; ++k) names.push_back(file_name(options.seed, std::size_t(k)));
    if (std::set<std::string>(names.begin(), names.end()).size() != names.size()) {
      std::cerr << "make_sample_series: file names collide for seed " << options.seed << "\n";
      return 1;
    }
    // Refuse to mix series: other .dcm files in OUTDIR (say from another seed) would be read
    // with ours by anyone pointing a loader at the folder.
    if (std::filesystem::is_directory(options.out_dir)) {
      for (const auto& entry : std::filesystem::directory_iterator(options.out_dir)) {
        const std::string name = entry.path().filename().string();
        if (entry.path().extension() == ".dcm" &&
            std::find(names.begin(), names.end(), name) == names.end()) {
          std::cerr << "make_sample_series: " << options.out_dir.string()
                    << " holds other DICOM files (" << name << "); empty it first\n";
          return 1;
        }
      }
    }

    const std::vector<std::int32_t> stored = render(HeadPhantom(), options.seed);
    const std::vector<ctw::CtSliceSpec> specs = make_specs(stored, options.seed);
    const auto paths = ctw::write_series(
        specs, options.out_dir,
        [&names](std::size_t index, const ctw::CtSliceSpec&) { return names[index]; });

    std::uintmax_t bytes = 0;
    for (const auto& path : paths) bytes += std::filesystem::file_size(path);
    std::cout << "wrote " << paths.size() << " slices (" << bytes << " bytes) to "
              << options.out_dir.string() << " (seed " << options.seed << ")\n";
    return 0;
  } catch (const std::exception& error) {
    std::cerr << "make_sample_series: " << error.what() << "\n";
    return 1;
  }
}
