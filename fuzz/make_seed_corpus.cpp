// make_seed_corpus OUT_DIR: writes the starting corpora of the fuzz targets, so no binary
// seed lives in git.
//   OUT_DIR/dicom_file/      small CT files from ct_writer in every transfer syntax and
//                            container, plus an Enhanced-CT-like multi-frame header and a
//                            few broken variants (truncated, no pixel data, bad geometry);
//   OUT_DIR/series_geometry/ byte strings decoding to regular, gapped and tilted stacks;
//   OUT_DIR/extract/         byte strings decoding to a ball, a saddle and a checkerboard.
#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <zip.h>

#include "ct_writer/ct_writer.h"
#include "seg/seg_writer.h"
#include "support/volume_file_writers.h"

namespace {

namespace fs = std::filesystem;
namespace ctw = typemerge::ct_writer;

void write_bytes(const fs::path& file, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

void dicom_seeds(const fs::path& folder) {
  using TS = ctw::TransferSyntax;
  const TS syntaxes[] = {TS::implicit_little, TS::explicit_little, TS::explicit_big,
                         TS::deflated_little, TS::jpeg_lossless,  TS::jpeg_ls_lossless,
                         TS::rle_lossless};
  auto base = [] {
    ctw::CtSliceSpec spec;
    spec.rows = 4;
    spec.columns = 4;
    spec.pixels.resize(16);
    for (std::size_t i = 0; i < spec.pixels.size(); ++i) {
      spec.pixels[i] = static_cast<std::uint16_t>(i * 200);
    }
    return spec;
  };
  int n = 0;
  for (TS syntax : syntaxes) {
    ctw::CtSliceSpec spec = base();
    spec.transfer_syntax = syntax;
    ctw::write_ct_slice(spec, folder / ("syntax_" + std::to_string(n++) + ".dcm"));
  }
  ctw::CtSliceSpec spec = base();
  spec.container = ctw::Container::no_preamble;
  ctw::write_ct_slice(spec, folder / "no_preamble.dcm");
  spec.container = ctw::Container::dataset_only;
  ctw::write_ct_slice(spec, folder / "dataset_only.dcm");
  spec = base();
  spec.pixel_representation = 1;
  spec.pixel_padding_value = -2000;
  spec.bits_stored = 16;
  spec.high_bit = 15;
  ctw::write_ct_slice(spec, folder / "signed_padding.dcm");
  spec = base();
  spec.bits_allocated = 8;
  spec.bits_stored = 8;
  spec.high_bit = 7;
  ctw::write_ct_slice(spec, folder / "eight_bit.dcm");
  spec = base();
  spec.extra = {{{0x0028, 0x0008}, "2"}};  // NumberOfFrames without functional groups
  ctw::write_ct_slice(spec, folder / "two_frames.dcm");
  spec = base();
  spec.truncate_to_bytes = 300;
  ctw::write_ct_slice(spec, folder / "truncated.dcm");
  spec = base();
  spec.omit = {ctw::kPixelDataTag};
  ctw::write_ct_slice(spec, folder / "no_pixels.dcm");
  spec = base();
  spec.pixel_spacing = "0\\1";
  ctw::write_ct_slice(spec, folder / "zero_spacing.dcm");
}

void geometry_seeds(const fs::path& folder) {
  // Layout (fuzz_series_geometry.cpp): policy, orientation pick, two spacings, base, step,
  // slice count − 1, then per slice: variant, image type, series number, path, frames, frame,
  // SOP instance, slice index. Small reals are "mode byte ≥ 2, then int8 × 0.5 mm".
  auto small = [](std::vector<std::uint8_t>& b, std::int8_t half_mm) {
    b.push_back(2);
    b.push_back(static_cast<std::uint8_t>(half_mm));
  };
  for (int seed = 0; seed < 4; ++seed) {
    std::vector<std::uint8_t> b;
    b.push_back(seed == 1 ? 1 : 0);        // resample for the gapped one
    b.push_back(seed == 3 ? 3 : 0);        // tilted orientation for the last
    small(b, 1);
    small(b, 1);                           // 0.5 mm pixels
    small(b, 0); small(b, 0); small(b, 0);  // base
    small(b, 0); small(b, 0); small(b, 4);  // step 2 mm in z
    b.push_back(5);                        // six slices
    for (std::uint8_t k = 0; k < 6; ++k) {
      b.insert(b.end(), {0, 0, 0, k, 0, 0, k});
      b.push_back(seed == 1 && k >= 3 ? static_cast<std::uint8_t>(k + 2) : k);
    }
    write_bytes(folder / ("stack_" + std::to_string(seed)), b);
  }
}

void extract_seeds(const fs::path& folder) {
  for (int seed = 0; seed < 3; ++seed) {
    std::vector<std::uint8_t> b;
    b.push_back(seed == 2 ? 0 : 1);  // scheme: levels or bytes
    b.insert(b.end(), {6, 6, 6});
    b.push_back(seed == 0 ? 0 : 1);  // iso
    b.push_back(0);
    for (int k = 0; k < 6; ++k) {
      for (int j = 0; j < 6; ++j) {
        for (int i = 0; i < 6; ++i) {
          const int d2 = (i - 3) * (i - 3) + (j - 3) * (j - 3) + (k - 3) * (k - 3);
          if (seed == 0) b.push_back(static_cast<std::uint8_t>(d2 < 6 ? 20 : 0));
          if (seed == 1) b.push_back(static_cast<std::uint8_t>((i - 3) * (j - 3)));
          if (seed == 2) b.push_back(static_cast<std::uint8_t>((i + j + k) % 2 ? 3 : 0));
        }
      }
    }
    write_bytes(folder / ("volume_" + std::to_string(seed)), b);
  }
}

// NIfTI-1 and -2, both byte orders, a few types, each geometry source, one gzip.
void nifti_seeds(const fs::path& folder) {
  namespace t = typemerge::test;
  t::NiftiSpec spec;
  spec.dim = {3, 3, 2, 2, 1, 1, 1, 1};
  for (int v = 0; v < 12; ++v) spec.values.push_back(v % 3);
  int n = 0;
  for (int version : {1, 2}) {
    for (int type : {t::kDtUint8, t::kDtInt16, t::kDtFloat32, t::kDtFloat64}) {
      spec.version = version;
      spec.datatype = type;
      spec.big_endian = (n % 2) == 1;
      spec.sform_code = n % 3 == 0 ? 1 : 0;
      spec.qform_code = n % 3 == 1 ? 1 : 0;
      spec.quatern = {0.1, 0.2, 0.3};
      write_bytes(folder / ("nifti_" + std::to_string(n++) + ".nii"), t::nifti_bytes(spec));
    }
  }
  spec.version = 1;
  write_bytes(folder / "nifti_gz.nii.gz", t::gzip_bytes(t::nifti_bytes(spec)));
}

// Raw and gzip, a Slicer layered segmentation with its keys, a spacings-only file.
void nrrd_seeds(const fs::path& folder) {
  namespace t = typemerge::test;
  std::vector<double> values;
  for (int v = 0; v < 24; ++v) values.push_back(v % 4);
  const std::string geometry =
      "dimension: 3\nsizes: 4 3 2\nspace: left-posterior-superior\n"
      "space directions: (0.5,0,0) (0,0.5,0) (0,0,2)\nspace origin: (1,2,3)\n";
  write_bytes(folder / "raw.nrrd", t::nrrd_bytes("type: short\n" + geometry +
                                                     "endian: little\nencoding: raw\n",
                                                 t::raw_samples<std::int16_t>(values), false));
  write_bytes(folder / "gzip.nrrd", t::nrrd_bytes("type: float\n" + geometry +
                                                      "endian: big\nencoding: gzip\n",
                                                  t::raw_samples<float>(values, true), true));
  write_bytes(folder / "spacings.nrrd",
              t::nrrd_bytes("type: uchar\ndimension: 3\nsizes: 4 3 2\nspacings: 1 1 2\n"
                            "encoding: raw\n",
                            t::raw_samples<std::uint8_t>(values), false));
  std::vector<double> layered;
  for (double v : values) {
    layered.push_back(v == 1 ? 1 : 0);
    layered.push_back(v >= 2 ? v - 1 : 0);
  }
  write_bytes(folder / "layered.seg.nrrd",
              t::nrrd_bytes("type: uchar\ndimension: 4\nsizes: 2 4 3 2\n"
                            "kinds: list domain domain domain\nspace: RAS\n"
                            "space directions: none (1,0,0) (0,1,0) (0,0,1)\n"
                            "space origin: (0,0,0)\nencoding: gzip\n"
                            "Segment0_Name:=a\nSegment0_Color:=1 0 0\n"
                            "Segment0_LabelValue:=1\nSegment0_Layer:=0\n"
                            "Segment1_Name:=b\nSegment1_LabelValue:=1\nSegment1_Layer:=1\n"
                            "Segment2_Name:=c\nSegment2_LabelValue:=2\nSegment2_Layer:=1\n",
                            t::raw_samples<std::uint8_t>(layered), true));
}

// Binary and fractional SEGs: overlapping segments, shuffled frames, a gap, colours.
void seg_seeds(const fs::path& folder) {
  namespace t = typemerge::test;
  t::SynthSeg spec;
  spec.segments = {{"a", std::array<std::uint16_t, 3>{41661, 41167, 40792}}, {"b", std::nullopt}};
  spec.frames.push_back({1, {0, 0, 4}, t::box_pixels(spec, 0, 1, 0, 2)});
  spec.frames.push_back({1, {0, 0, 0}, t::box_pixels(spec, 1, 2, 1, 3)});
  spec.frames.push_back({2, {0, 0, 2}, t::box_pixels(spec, 0, 3, 0, 5)});
  t::write_seg(spec, folder / "binary.dcm");
  spec.spacing_between_slices = 2.0;
  spec.orientation = {0, 1, 0, 0, 0, -1};
  t::write_seg(spec, folder / "sagittal.dcm");
  spec.fractional = true;
  spec.max_fractional_value = 100;
  for (auto& frame : spec.frames) {
    for (auto& v : frame.pixels) v = static_cast<std::uint8_t>(v * 70);
  }
  t::write_seg(spec, folder / "fractional.dcm");
}

// Small archives: two DICOM slices (one stored, one deflated) in folders, and an empty one.
void zip_seeds(const fs::path& folder) {
  ctw::CtSliceSpec spec;
  spec.rows = 4;
  spec.columns = 4;
  spec.pixels.assign(16, 100);
  const fs::path slice = folder / "slice.tmp";
  ctw::write_ct_slice(spec, slice);
  int code = 0;
  zip_t* archive = zip_open((folder / "two.zip").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
  for (const char* name : {"study/a.dcm", "study/b.dcm"}) {
    zip_source_t* source = zip_source_file(archive, slice.c_str(), 0, -1);
    const zip_int64_t index = zip_file_add(archive, name, source, ZIP_FL_OVERWRITE);
    if (name[6] == 'a') {
      zip_set_file_compression(archive, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
    }
  }
  zip_dir_add(archive, "study/", 0);
  zip_close(archive);
  fs::remove(slice);
  archive = zip_open((folder / "empty.zip").c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
  zip_source_t* source = zip_source_buffer(archive, "x", 1, 0);
  zip_file_add(archive, "x", source, 0);
  zip_close(archive);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seed_corpus OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  for (const char* name :
       {"dicom_file", "series_geometry", "extract", "nifti", "nrrd", "seg", "zip"}) {
    fs::create_directories(out / name);
  }
  dicom_seeds(out / "dicom_file");
  geometry_seeds(out / "series_geometry");
  extract_seeds(out / "extract");
  nifti_seeds(out / "nifti");
  nrrd_seeds(out / "nrrd");
  seg_seeds(out / "seg");
  zip_seeds(out / "zip");
  return 0;
}
