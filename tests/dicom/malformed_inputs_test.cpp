// Malformed and awkward inputs, generated here with the project's CT writer: each gives its
// documented outcome (loads, loads with a warning, a file skipped for a reason, or the series
// refused for a reason) and never a crash (this suite also runs under ASan/UBSan).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <ostream>

#include "ct_writer/ct_writer.h"
#include "dicom/pixel_reader.h"
#include "dicom/series_loader.h"
#include "support/scratch_files.h"

namespace typemerge::dicom {
namespace {

namespace fs = std::filesystem;
using ct_writer::CtSliceSpec;
using ct_writer::SeriesLayout;

// A small valid axial series: 12×10 pixels, 6 slices 2 mm apart, a bright block in the middle.
SeriesLayout small_layout(const std::string& seed = "malformed") {
  SeriesLayout layout;
  layout.uid_seed = seed;
  layout.columns = 12;
  layout.rows = 10;
  layout.slices = 6;
  layout.pixel_spacing = {0.8, 0.7};
  layout.slice_spacing = 2.0;
  layout.origin = {-5, -4, 10};
  layout.hu = [](int i, int j, int k) {
    return (i > 3 && i < 8 && j > 2 && j < 7 && k > 0 && k < 5) ? 700.0 : -1000.0 + 10 * i;
  };
  return layout;
}

struct Expectation {
  bool loads = true;                  // a default series exists and load_series succeeds
  std::optional<std::size_t> slices;  // slices of the loaded volume
  std::string skipped;                // a skipped file's reason contains this
  std::string refused;                // the (only) volume series' error contains this
  std::string warning;                // a load or geometry warning contains this
  std::size_t volume_series = 1;      // series with role volume
};

struct Case {
  std::string name;
  std::function<void(const fs::path&)> make;
  Expectation expect;
  std::function<void(ScanOptions&)> options = nullptr;
  std::function<void(const LoadedSeries&)> check = nullptr;
};

// Failure messages name the case instead of dumping its bytes.
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

void write_series(const fs::path& dir, std::vector<CtSliceSpec> specs,
                  const std::function<void(std::size_t, CtSliceSpec&)>& edit = nullptr) {
  for (std::size_t k = 0; k < specs.size(); ++k) {
    if (edit) edit(k, specs[k]);
    ct_writer::write_ct_slice(specs[k], dir / ("slice" + std::to_string(k) + ".dcm"));
  }
}

std::function<void(const fs::path&)> edited(std::function<void(std::size_t, CtSliceSpec&)> edit,
                                            SeriesLayout layout = small_layout()) {
  return [edit, layout](const fs::path& dir) {
    write_series(dir, ct_writer::make_axial_series(layout), edit);
  };
}

std::function<void(const fs::path&)> with_layout(std::function<void(SeriesLayout&)> change) {
  SeriesLayout layout = small_layout();
  change(layout);
  return edited(nullptr, layout);
}

void write_bytes(const fs::path& file, const std::string& bytes) {
  std::ofstream(file, std::ios::binary) << bytes;
}

// A Part-10 file whose data set is `depth` nested sequences of undefined length: DCMTK parses
// these recursively, so without the pre-scan this overflows the stack.
void write_nested_bomb(const fs::path& file, int depth) {
  auto u16 = [](std::string& s, unsigned v) { s += char(v & 0xFF); s += char((v >> 8) & 0xFF); };
  auto u32 = [&](std::string& s, unsigned v) { u16(s, v & 0xFFFF); u16(s, v >> 16); };
  std::string meta_value = "1.2.840.10008.1.2.1";
  meta_value += '\0';
  std::string out(128, '\0');
  out += "DICM";
  u16(out, 0x0002); u16(out, 0x0010); out += "UI"; u16(out, static_cast<unsigned>(meta_value.size()));
  out += meta_value;
  for (int d = 0; d < depth; ++d) {
    u16(out, 0x0040); u16(out, 0xA730); out += "SQ"; u16(out, 0); u32(out, 0xFFFFFFFF);  // sequence
    u16(out, 0xFFFE); u16(out, 0xE000); u32(out, 0xFFFFFFFF);                            // item
  }
  write_bytes(file, out);
}

// Replaces the explicit VR of the first element with `tag` (little endian) by `vr`.
void patch_vr(const fs::path& file, std::uint16_t group, std::uint16_t element, const char* vr) {
  std::ifstream in(file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key{char(group & 0xFF), char(group >> 8), char(element & 0xFF),
                        char(element >> 8)};
  const std::size_t at = bytes.find(key, 132);
  ASSERT_NE(at, std::string::npos);
  bytes[at + 4] = vr[0];
  bytes[at + 5] = vr[1];
  write_bytes(file, bytes);
}

std::vector<Case> cases() {
  std::vector<Case> all;
  auto add = [&](Case c) { all.push_back(std::move(c)); };

  add({"valid_series", edited(nullptr), {.slices = 6}});
  add({"file_names_reverse_slice_order", [](const fs::path& dir) {
         auto specs = ct_writer::make_axial_series(small_layout());
         for (std::size_t k = 0; k < specs.size(); ++k) {
           specs[k].instance_number = std::to_string(specs.size() - k);
           ct_writer::write_ct_slice(specs[k], dir / ("z" + std::to_string(9 - k) + ".dcm"));
         }
       }, {.slices = 6}, nullptr, [](const LoadedSeries& loaded) {
         EXPECT_NEAR(loaded.volume.geometry().origin[2], 10.0, 1e-9);  // lowest slice first
         EXPECT_NEAR(loaded.volume.geometry().axes[2][2], 2.0, 1e-9);
       }});
  add({"truncated_pixel_data", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.truncate_to_bytes = 1300;  // inside the 240 pixel bytes at the end
       }), {.slices = 5, .skipped = "truncated"}});
  add({"truncated_inside_header", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.truncate_to_bytes = 200;
       }), {.slices = 5, .skipped = "damaged DICOM"}});
  add({"huge_dimensions", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.rows = s.columns = 65535;
       }), {.slices = 5, .skipped = "exceeds the per-file memory limit"}});
  add({"huge_frame_count", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.extra.push_back({{0x0028, 0x0008}, "1000000000"});
       }), {.slices = 5, .skipped = "NumberOfFrames"}});
  add({"short_pixel_data", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.pixels.resize(s.pixels.size() / 2);
       }), {.slices = 5, .skipped = "pixel data is"}});
  add({"missing_pixel_data", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.omit.push_back(ct_writer::kPixelDataTag);
       }), {.slices = 5, .skipped = "no pixel data"}});
  add({"wrong_vr_for_rows", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         patch_vr(dir / "slice5.dcm", 0x0028, 0x0010, "SS");
       }, {.slices = 5, .skipped = "Rows has value representation SS"}});
  add({"nan_pixel_spacing", edited([](std::size_t, CtSliceSpec& s) { s.pixel_spacing = "NaN\\NaN"; }),
       {.loads = false, .skipped = "PixelSpacing 'NaN\\NaN' is not 2 finite numbers", .volume_series = 0}});
  add({"inf_pixel_spacing", edited([](std::size_t, CtSliceSpec& s) { s.pixel_spacing = "inf\\1"; }),
       {.loads = false, .skipped = "finite", .volume_series = 0}});
  add({"negative_pixel_spacing", edited([](std::size_t, CtSliceSpec& s) { s.pixel_spacing = "-0.7\\0.7"; }),
       {.loads = false, .skipped = "not positive", .volume_series = 0}});
  add({"zero_pixel_spacing", edited([](std::size_t, CtSliceSpec& s) { s.pixel_spacing = "0\\0"; }),
       {.loads = false, .skipped = "not positive", .volume_series = 0}});
  add({"nan_position", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 2) s.image_position_patient = "NaN\\0\\4";
       }), {.loads = false, .skipped = "ImagePositionPatient", .refused = "missing slice"}});
  add({"nan_orientation", edited([](std::size_t, CtSliceSpec& s) {
         s.image_orientation_patient = "1\\0\\0\\0\\NaN\\0";
       }), {.loads = false, .skipped = "ImageOrientationPatient", .volume_series = 0}});
  add({"non_orthogonal_orientation", edited([](std::size_t, CtSliceSpec& s) {
         s.image_orientation_patient = "1\\0\\0\\0.5\\0.8660254\\0";
       }), {.loads = false, .refused = "orthogonal"}});
  add({"zero_rescale_slope", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 0) s.rescale_slope = "0";
       }), {.slices = 5, .skipped = "RescaleSlope is 0"}});
  add({"nan_rescale_slope", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 0) s.rescale_slope = "NaN";
       }), {.slices = 5, .skipped = "RescaleSlope"}});
  add({"missing_position", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 0) s.omit.push_back(ct_writer::kImagePositionPatientTag);
       }), {.slices = 5, .skipped = "missing ImagePositionPatient"}});
  add({"bits_stored_above_allocated", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 0) s.bits_stored = 20;
       }), {.slices = 5, .skipped = "inconsistent BitsStored"}});
  add({"bits_allocated_32", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 0) { s.bits_allocated = 32; s.bits_stored = 32; s.high_bit = 31; }
       }), {.slices = 5, .skipped = "BitsAllocated 32"}});
  add({"mixed_series", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout("first")));
         SeriesLayout other = small_layout("second");
         other.slices = 9;
         other.series_number = 2;
         const fs::path sub = dir / "other";
         fs::create_directories(sub);
         write_series(sub, ct_writer::make_axial_series(other));
       }, {.slices = 9, .volume_series = 2}});
  add({"duplicate_file", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         fs::copy_file(dir / "slice3.dcm", dir / "copy_of_slice3.dcm");
       }, {.slices = 6, .warning = "duplicate image"}});
  add({"two_images_at_one_position", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 4) s.image_position_patient = "-5\\-4\\16";  // same as slice 3
       }), {.loads = false, .refused = "same position"}});
  add({"missing_slice", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         fs::remove(dir / "slice2.dcm");
       }, {.loads = false, .refused = "1 missing slice"}});
  add({"missing_slice_resampled_on_request", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         fs::remove(dir / "slice2.dcm");
       }, {.slices = 6, .warning = "resampled"},
       [](ScanOptions& o) { o.geometry.spacing = SpacingPolicy::resample; }});
  add({"uneven_spacing", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.image_position_patient = "-5\\-4\\21";  // step 1 mm instead of 2
       }), {.loads = false, .refused = "not uniform"}});
  add({"gantry_tilt", with_layout([](SeriesLayout& l) {
         const double t = 20.0 * M_PI / 180;
         l.orientation = {1, 0, 0, 0, std::cos(t), -std::sin(t)};
         l.slice_step = ct_writer::Vec3{0, 0, 2.0};  // positions advance along the table
       }), {.slices = 6, .warning = "gantry tilt of 20.00 degrees"}, nullptr,
       [](const LoadedSeries& loaded) { EXPECT_NEAR(loaded.tilt_degrees, 20.0, 1e-6); }});
  add({"localizer_inside_series", [](const fs::path& dir) {
         auto specs = ct_writer::make_axial_series(small_layout());
         CtSliceSpec scout = specs[0];
         scout.sop_instance_uid = ct_writer::make_uid("scout");
         scout.image_orientation_patient = "1\\0\\0\\0\\0\\-1";
         write_series(dir, specs);
         ct_writer::write_ct_slice(scout, dir / "scout.dcm");
       }, {.slices = 6, .volume_series = 1}});
  add({"localizer_by_image_type", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         SeriesLayout scout = small_layout("scout");
         scout.slices = 1;
         auto specs = ct_writer::make_axial_series(scout);
         specs[0].image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
         ct_writer::write_ct_slice(specs[0], dir / "scout.dcm");
       }, {.slices = 6}});
  add({"colour_image", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) {
           s.samples_per_pixel = 3;
           s.photometric = "RGB";
           s.bits_allocated = 8; s.bits_stored = 8; s.high_bit = 7;
           s.pixels.assign(s.pixels.size() * 3 / 2, 0);
         }
       }), {.slices = 5, .skipped = "colour image"}});
  add({"mr_modality", edited([](std::size_t, CtSliceSpec& s) {
         s.modality = "MR";
         s.sop_class_uid = "1.2.840.10008.5.1.4.1.1.4";
       }), {.loads = false, .skipped = "modality MR, not CT", .volume_series = 0}});
  add({"mr_modality_with_override", edited([](std::size_t, CtSliceSpec& s) {
         s.modality = "MR";
         s.sop_class_uid = "1.2.840.10008.5.1.4.1.1.4";
       }), {.slices = 6}, [](ScanOptions& o) { o.header.allow_non_ct_modality = true; }});
  add({"secondary_capture", edited([](std::size_t k, CtSliceSpec& s) {
         if (k == 5) s.sop_class_uid = std::string(ct_writer::kSecondaryCaptureImageStorage);
       }), {.slices = 5, .skipped = "secondary capture"}});
  add({"text_file_and_empty_file", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         write_bytes(dir / "notes.txt", "These are not DICOM files.\n");
         write_bytes(dir / "empty", "");
       }, {.slices = 6, .skipped = "not a DICOM file"}});
  add({"deeply_nested_sequences", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         write_nested_bomb(dir / "bomb.dcm", 200000);
       }, {.slices = 6, .skipped = "nested more than"}});
  add({"no_preamble", edited([](std::size_t, CtSliceSpec& s) {
         s.container = ct_writer::Container::no_preamble;
       }), {.slices = 6}});
  add({"no_meta_header", edited([](std::size_t, CtSliceSpec& s) {
         s.container = ct_writer::Container::dataset_only;
         s.transfer_syntax = ct_writer::TransferSyntax::implicit_little;
       }), {.slices = 6}});
  for (auto syntax : {ct_writer::TransferSyntax::explicit_big, ct_writer::TransferSyntax::deflated_little,
                      ct_writer::TransferSyntax::jpeg_lossless, ct_writer::TransferSyntax::jpeg_ls_lossless,
                      ct_writer::TransferSyntax::rle_lossless}) {
    SeriesLayout layout = small_layout();
    layout.transfer_syntax = syntax;
    add({std::string("transfer_syntax_") + ct_writer::to_uid(syntax), edited(nullptr, layout),
         {.slices = 6}, nullptr, [](const LoadedSeries& loaded) {
           EXPECT_EQ(loaded.volume.at(5, 4, 2), 700.0f);   // inside the block
           EXPECT_EQ(loaded.volume.at(0, 0, 0), -1000.0f);
           EXPECT_EQ(loaded.volume.at(11, 0, 0), -890.0f);
         }});
  }
  add({"signed_pixels", with_layout([](SeriesLayout& l) {
         l.pixel_representation = 1;
         l.bits_stored = 12;
         l.high_bit = 11;
         l.rescale_intercept = 0;
       }), {.slices = 6}, nullptr, [](const LoadedSeries& loaded) {
         EXPECT_EQ(loaded.volume.at(0, 0, 0), -1000.0f);  // sign-extended from bit 11
         EXPECT_EQ(loaded.volume.at(5, 4, 2), 700.0f);
       }});
  add({"high_bit_above_bits_stored", with_layout([](SeriesLayout& l) {
         // 12 stored bits in bits 4..15: the stored value is the word shifted right by 4.
         l.bits_stored = 12;
         l.high_bit = 15;
         l.stored_value = [](int i, int j, int k) {
           const double hu = small_layout().hu(i, j, k);
           return static_cast<std::int32_t>(hu + 1024) << 4;
         };
       }), {.slices = 6}, nullptr, [](const LoadedSeries& loaded) {
         EXPECT_EQ(loaded.volume.at(5, 4, 2), 700.0f);
       }});
  add({"pixel_padding_becomes_air", edited([](std::size_t, CtSliceSpec& s) {
         s.pixel_padding_value = 0;  // stored 0 would be −1024 HU
         s.pixels[0] = 0;
       }), {.slices = 6}, nullptr, [](const LoadedSeries& loaded) {
         EXPECT_EQ(loaded.volume.at(0, 0, 0), kAirHu);
       }});
  add({"values_not_hounsfield", with_layout([](SeriesLayout& l) {
         l.rescale_intercept = 0;
         l.hu = [](int i, int, int) { return 100.0 * i; };
       }), {.slices = 6, .warning = "may not be Hounsfield"}});
  add({"symlinks_not_followed", [](const fs::path& dir) {
         write_series(dir, ct_writer::make_axial_series(small_layout()));
         fs::create_directory_symlink(dir, dir / "loop");           // a cycle
         fs::create_symlink(dir / "slice0.dcm", dir / "link.dcm");  // a second path to a file
       }, {.slices = 6}});
  add({"single_slice", with_layout([](SeriesLayout& l) { l.slices = 1; }),
       {.loads = false, .refused = "single slice"}});
  return all;
}

class MalformedInput : public ::testing::TestWithParam<Case> {};

TEST_P(MalformedInput, GivesItsDocumentedOutcome) {
  const Case& c = GetParam();
  const fs::path dir = test::fresh_dir(c.name, "typemerge_malformed_");
  c.make(dir);
  ScanOptions options;
  if (c.options) c.options(options);
  const FolderScan scan = scan_folder(dir, options);
  const Expectation& e = c.expect;

  if (!e.skipped.empty()) {
    bool found = false;
    for (const auto& file : scan.skipped) found |= file.reason.find(e.skipped) != std::string::npos;
    std::string reasons;
    for (const auto& file : scan.skipped) reasons += "\n  " + file.path.string() + ": " + file.reason;
    EXPECT_TRUE(found) << "no skipped file says '" << e.skipped << "'; skipped:" << reasons;
  }
  std::size_t volume_series = 0;
  for (const auto& s : scan.series) volume_series += s.role == SeriesRole::volume;
  EXPECT_EQ(volume_series, e.volume_series);
  if (!e.refused.empty()) {
    bool found = false;
    for (const auto& s : scan.series) found |= s.geometry.error.find(e.refused) != std::string::npos;
    EXPECT_TRUE(found) << "no series refused with '" << e.refused << "'";
  }
  EXPECT_EQ(scan.default_series.has_value(), e.loads);
  if (!scan.default_series) return;
  const LoadedSeries loaded = load_series(scan.series[*scan.default_series]);
  if (e.slices) EXPECT_EQ(loaded.volume.size().nz, static_cast<std::int64_t>(*e.slices));
  if (!e.warning.empty()) {
    bool found = false;
    for (const auto& w : loaded.warnings) found |= w.find(e.warning) != std::string::npos;
    EXPECT_TRUE(found) << "no warning says '" << e.warning << "'";
  }
  if (c.check) c.check(loaded);
  if (!HasFailure()) fs::remove_all(dir);  // kept for inspection when the case fails
}

INSTANTIATE_TEST_SUITE_P(Generated, MalformedInput, ::testing::ValuesIn(cases()),
                         [](const auto& info) {
                           std::string name = info.param.name;
                           for (char& ch : name) if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return name;
                         });

}  // namespace
}  // namespace typemerge::dicom
