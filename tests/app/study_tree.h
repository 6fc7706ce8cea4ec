// A generated tree of studies for the batch tests, laid out like an archive export:
//
//   root/README.txt                         not DICOM
//   root/siteA/p01/studyA/{thin,thick,scout} study A: 1 mm series (chosen: most slices),
//                                            2 mm series, a one-slice localizer
//   root/siteA/p01/notes.txt                 not DICOM
//   root/siteA/p02/studyB/{soft,sharp}       study B: two 10-slice series, 2 mm "SOFT" and
//                                            1 mm "SHARP" (chosen: same count, thinner)
//   root/siteB/DOE_JOHN/studyC/s1            study C: its folder spells the patient's name;
//                                            values are not Hounsfield units (fails in convert)
//   root/siteB/studyD/s1                     study D: a slice missing (refused when planning)
//   root/siteC/studyE/s1                     study E: one plain series
//
// Every series holds a ball (bone inside air) so bone and skin presets find a surface.
//
// Folders no study comes of (issue 16): write_damaged_dicom (a DICM preamble, then garbage),
// write_truncated_copy (an interrupted copy of a slice) and write_mr_series (not CT).
#pragma once

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "ct_writer/ct_writer.h"

namespace typemerge::test {

struct SeriesSpec {
  std::string seed;
  std::string description;
  std::string kernel = "STANDARD";
  int slices = 12;
  double spacing = 1.0;
  double radius = 5.0;
  int series_number = 1;
  double intercept = -1024;
  bool not_hounsfield = false;  // air 0, bone 2000 with intercept 0
  int drop_slice = -1;
  bool localizer = false;
};

inline void write_test_series(const std::filesystem::path& dir, const std::string& study_seed,
                              const SeriesSpec& s, const std::string& patient_name = "Doe^John",
                              const std::string& patient_id = "PID0042") {
  ct_writer::SeriesLayout layout;
  layout.uid_seed = study_seed + "/" + s.seed;
  layout.columns = 24;
  layout.rows = 24;
  layout.slices = s.localizer ? 1 : s.slices;
  layout.pixel_spacing = {1.0, 1.0};
  layout.slice_spacing = s.spacing;
  layout.origin = {-12, -12, 0};
  layout.rescale_intercept = s.not_hounsfield ? 0 : s.intercept;
  layout.series_description = s.description;
  layout.series_number = s.series_number;
  const double radius = s.radius;
  const double spacing = s.spacing;
  const int slices = s.slices;
  const bool not_hu = s.not_hounsfield;
  layout.hu = [=](int i, int j, int k) {
    const double d = std::hypot(i - 11.5, j - 11.5, (k - (slices - 1) / 2.0) * spacing);
    if (not_hu) return d < radius ? 2000.0 : 0.0;
    return d < radius ? 1000.0 : -1000.0;
  };
  auto specs = ct_writer::make_axial_series(layout);
  std::filesystem::create_directories(dir);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    if (static_cast<int>(k) == s.drop_slice) continue;
    auto spec = specs[k];
    // Every series of a study shares its study UID.
    spec.study_instance_uid = ct_writer::make_uid(study_seed + "/study");
    spec.frame_of_reference_uid = ct_writer::make_uid(study_seed + "/for");
    spec.patient_name = patient_name;
    spec.patient_id = patient_id;
    spec.convolution_kernel = s.kernel;
    if (s.localizer) spec.image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
    ct_writer::write_ct_slice(spec, dir / ("im" + std::to_string(k)));
  }
}

// 128 zero bytes, "DICM", a meta element longer than the file, garbage: damaged DICOM.
inline void write_damaged_dicom(const std::filesystem::path& file) {
  std::string bytes(128, '\0');
  bytes += "DICM";
  bytes += std::string("\x02\x00\x10\x00UI\xff\x7f", 8);
  bytes += "garbage garbage garbage";
  std::filesystem::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << bytes;
}

// The first half of `source`: a copy cut off in the pixel data (the headers, with the
// patient's name, are all there).
inline void write_truncated_copy(const std::filesystem::path& source,
                                 const std::filesystem::path& file) {
  std::ifstream in(source, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  bytes.resize(bytes.size() / 2);
  std::filesystem::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << bytes;
}

// `slices` MR images (MR Image Storage, modality MR): refused unless --allow-non-ct.
inline void write_mr_series(const std::filesystem::path& dir, const std::string& seed, int slices) {
  ct_writer::SeriesLayout layout;
  layout.uid_seed = seed;
  layout.columns = 16;
  layout.rows = 16;
  layout.slices = slices;
  layout.hu = [](int, int, int) { return 100.0; };
  std::filesystem::create_directories(dir);
  auto specs = ct_writer::make_axial_series(layout);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    specs[k].sop_class_uid = "1.2.840.10008.5.1.4.1.1.4";
    specs[k].modality = "MR";
    ct_writer::write_ct_slice(specs[k], dir / ("mr" + std::to_string(k)));
  }
}

inline void write_study_tree(const std::filesystem::path& root) {
  namespace fs = std::filesystem;
  fs::create_directories(root);
  std::ofstream(root / "README.txt") << "not a DICOM file\n";
  const fs::path a = root / "siteA" / "p01" / "studyA";
  write_test_series(a / "thin", "A", {"thin", "thin 1mm", "STANDARD", 14, 1.0, 5.0, 2});
  write_test_series(a / "thick", "A", {"thick", "thick 2mm", "STANDARD", 7, 2.0, 5.0, 3});
  SeriesSpec scout{"scout", "scout"};
  scout.localizer = true;
  scout.series_number = 1;
  write_test_series(a / "scout", "A", scout);
  std::ofstream(root / "siteA" / "p01" / "notes.txt") << "notes\n";
  const fs::path b = root / "siteA" / "p02" / "studyB";
  write_test_series(b / "soft", "B", {"soft", "soft 2mm", "SOFT", 10, 2.0, 4.0, 2});
  write_test_series(b / "sharp", "B", {"sharp", "sharp 1mm", "SHARP", 10, 1.0, 4.0, 3});
  SeriesSpec c{"c1", "not hu"};
  c.not_hounsfield = true;
  write_test_series(root / "siteB" / "DOE_JOHN" / "studyC" / "s1", "C", c);
  SeriesSpec d{"d1", "gap"};
  d.drop_slice = 5;
  write_test_series(root / "siteB" / "studyD" / "s1", "D", d);
  write_test_series(root / "siteC" / "studyE" / "s1", "E", {"e1", "plain", "STANDARD", 10, 1.5, 6.0});
}

}  // namespace typemerge::test
