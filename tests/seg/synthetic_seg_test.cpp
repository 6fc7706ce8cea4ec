// SEGs written by DCMTK's dcmseg itself: layers for overlaps, frame order, missing frames,
// fractional thresholds, colours, geometry, refusal of frames off the grid, privacy.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "seg/seg_reader.h"
#include "seg/seg_writer.h"
#include "support/scratch_files.h"

namespace typemerge::seg {
namespace {

using test::SynthFrame;
using test::SynthSeg;

// Voxels of `label` in `layer`.
std::int64_t count(const core::Volume& layer, float label) {
  return std::count(layer.samples().begin(), layer.samples().end(), label);
}

std::filesystem::path written(const SynthSeg& spec, const std::string& name) {
  const auto dir = test::fresh_dir("seg_" + name);
  const auto file = dir / "seg.dcm";
  test::write_seg(spec, file);
  return file;
}

// Two segments on three slices 2 mm apart, z = 10, 12, 14.
SynthSeg two_segments() {
  SynthSeg spec;
  spec.segments = {{"Liver", std::nullopt}, {"Tumour", std::nullopt}};
  for (int k = 0; k < 3; ++k) {
    spec.frames.push_back({1, {-5, 7, 10.0 + 2 * k}, test::box_pixels(spec, 0, 1, 0, 2)});
  }
  return spec;
}

TEST(SyntheticSeg, DisjointSegmentsShareOneLayer) {
  SynthSeg spec = two_segments();
  spec.frames.push_back({2, {-5, 7, 12}, test::box_pixels(spec, 2, 3, 3, 5)});
  const SegVolume seg = read_seg(written(spec, "disjoint"));
  ASSERT_EQ(seg.labels.layers.size(), 1u);
  ASSERT_EQ(seg.labels.segments.size(), 2u);
  EXPECT_EQ(seg.labels.segments[0].name, "Liver");
  EXPECT_EQ(seg.labels.segments[1].name, "Tumour");
  EXPECT_EQ(seg.labels.segments[0].label, 1);
  EXPECT_EQ(seg.labels.segments[1].label, 2);
  EXPECT_EQ(count(seg.labels.layers[0], 1.0f), 3 * 6);
  EXPECT_EQ(count(seg.labels.layers[0], 2.0f), 6);
  const core::VolumeSize size = seg.labels.layers[0].size();
  EXPECT_EQ(size, (core::VolumeSize{6, 4, 3}));
}

TEST(SyntheticSeg, OverlappingSegmentsGoToTwoLayers) {
  SynthSeg spec = two_segments();
  spec.segments.push_back({"Vessel", std::nullopt});
  spec.frames.push_back({2, {-5, 7, 12}, test::box_pixels(spec, 1, 3, 2, 5)});  // overlaps 1
  spec.frames.push_back({3, {-5, 7, 14}, test::box_pixels(spec, 3, 3, 0, 5)});  // overlaps none
  const SegVolume seg = read_seg(written(spec, "overlap"));
  ASSERT_EQ(seg.labels.layers.size(), 2u);
  EXPECT_EQ(seg.labels.segments[0].layer, 0u);
  EXPECT_EQ(seg.labels.segments[1].layer, 1u);
  EXPECT_EQ(seg.labels.segments[2].layer, 0u);
  EXPECT_EQ(count(seg.labels.layers[0], 1.0f), 18);
  EXPECT_EQ(count(seg.labels.layers[1], 2.0f), 3 * 4);
  EXPECT_EQ(count(seg.labels.layers[0], 3.0f), 6);
  EXPECT_EQ(seg.labels.layers[1].at(2, 1, 1), 2.0f);  // the shared voxel is in both
  EXPECT_EQ(seg.labels.layers[0].at(2, 1, 1), 1.0f);
}

TEST(SyntheticSeg, ShuffledFramesAndAMissingEmptyFrame) {
  SynthSeg spec;
  spec.segments = {{"Bone", std::nullopt}};
  // Slices at z = 0, 3, 6, 9, 12: slice 9 empty and left out, the rest written out of order,
  // each with a box whose width tells its slice.
  const std::vector<int> slices = {3, 0, 4, 1};
  for (int k : slices) {
    spec.frames.push_back({1, {0, 0, 3.0 * k}, test::box_pixels(spec, 0, 0, 0, k)});
  }
  const SegVolume seg = read_seg(written(spec, "shuffled"));
  ASSERT_EQ(seg.labels.layers.size(), 1u);
  const core::Volume& layer = seg.labels.layers[0];
  ASSERT_EQ(layer.size(), (core::VolumeSize{6, 4, 5}));
  for (int k = 0; k < 5; ++k) {
    std::int64_t in_slice = 0;
    for (int i = 0; i < 6; ++i) in_slice += layer.at(i, 0, k) != 0.0f ? 1 : 0;
    EXPECT_EQ(in_slice, k == 2 ? 0 : k + 1) << "slice " << k;
  }
  const core::Vec3 top = layer.geometry().apply(0, 0, 4);
  EXPECT_NEAR(top[2], 12.0, 1e-9);
  EXPECT_NEAR(layer.geometry().spacing(2), 3.0, 1e-9);
}

TEST(SyntheticSeg, GeometryFollowsOrientationAndSpacing) {
  SynthSeg spec;
  // Sagittal-like: rows along -y, columns along -z; normal = row × column.
  spec.orientation = {0, 1, 0, 0, 0, -1};
  spec.segments = {{"A", std::nullopt}};
  spec.frames.push_back({1, {4, -2, 30}, test::box_pixels(spec, 0, 0, 0, 0)});
  spec.frames.push_back({1, {6, -2, 30}, test::box_pixels(spec, 0, 0, 0, 0)});
  spec.spacing_between_slices = 1.0;
  const SegHeader header = read_seg_header(written(spec, "geometry"));
  EXPECT_EQ(header.size, (core::VolumeSize{6, 4, 3}));
  // normal = (0,1,0) × (0,0,-1) = (-1,0,0): slice 0 is the frame at x = 6.
  const core::Vec3 origin = header.geometry.apply(0, 0, 0);
  EXPECT_NEAR(origin[0], 6, 1e-9);
  EXPECT_NEAR(origin[1], -2, 1e-9);
  EXPECT_NEAR(origin[2], 30, 1e-9);
  const core::Vec3 far = header.geometry.apply(1, 1, 2);
  EXPECT_NEAR(far[0], 4, 1e-9);         // two 1 mm slices along the normal
  EXPECT_NEAR(far[1], -2 + 0.75, 1e-9);  // one column step along the row direction
  EXPECT_NEAR(far[2], 30 - 0.5, 1e-9);   // one row step along the column direction
  EXPECT_GT(header.geometry.determinant(), 0);
}

TEST(SyntheticSeg, ScatteredPixelsEverywhereInTheBitStream) {
  SynthSeg spec;
  spec.rows = 8;
  spec.columns = 16;
  spec.segments = {{"Dots", std::nullopt}};
  // Frame k: pixels (row k, column 3k + 1), the frame's last pixel, and a run across a byte.
  for (int k = 0; k < 3; ++k) {
    std::vector<std::uint8_t> pixels(128, 0);
    pixels[static_cast<std::size_t>(k * 16 + 3 * k + 1)] = 1;
    pixels[127] = 1;
    for (int c = 5; c <= 10; ++c) pixels[static_cast<std::size_t>(7 * 16 - 16 + c)] = 1;
    spec.frames.push_back({1, {0, 0, 1.0 * k}, pixels});
  }
  const SegVolume seg = read_seg(written(spec, "scattered"));
  const core::Volume& layer = seg.labels.layers.at(0);
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 8; ++j) {
      for (int i = 0; i < 16; ++i) {
        const bool expected = (j == k && i == 3 * k + 1) || (j == 7 && i == 15) ||
                              (j == 6 && i >= 5 && i <= 10);
        EXPECT_EQ(layer.at(i, j, k) != 0.0f, expected) << i << "," << j << "," << k;
      }
    }
  }
}

TEST(SyntheticSeg, FractionalIsThresholdedAtHalfTheMaximum) {
  SynthSeg spec;
  spec.fractional = true;
  spec.max_fractional_value = 200;
  spec.segments = {{"Prob", std::nullopt}};
  std::vector<std::uint8_t> pixels(24, 0);
  pixels[0] = 99;   // below 50 %
  pixels[1] = 100;  // exactly 50 %: inside
  pixels[2] = 200;
  pixels[23] = 150;
  spec.frames.push_back({1, {0, 0, 0}, pixels});
  const SegVolume seg = read_seg(written(spec, "fractional"));
  const core::Volume& layer = seg.labels.layers.at(0);
  EXPECT_EQ(layer.at(0, 0, 0), 0.0f);
  EXPECT_EQ(layer.at(1, 0, 0), 1.0f);
  EXPECT_EQ(layer.at(2, 0, 0), 1.0f);
  EXPECT_EQ(layer.at(5, 3, 0), 1.0f);
  EXPECT_EQ(count(layer, 1.0f), 3);
}

TEST(SyntheticSeg, ColoursFromCieLab) {
  SynthSeg spec = two_segments();
  spec.segments[0].cielab = std::array<std::uint16_t, 3>{41661, 41167, 40792};
  const SegVolume seg = read_seg(written(spec, "colour"));
  ASSERT_TRUE(seg.labels.segments[0].srgb.has_value());
  const auto rgb = *seg.labels.segments[0].srgb;
  EXPECT_NEAR(rgb[0], 221, 1);
  EXPECT_NEAR(rgb[1], 130, 1);
  EXPECT_NEAR(rgb[2], 101, 1);
  EXPECT_FALSE(seg.labels.segments[1].srgb.has_value());
}

TEST(SyntheticSeg, AFrameOffTheGridIsRefused) {
  SynthSeg spec = two_segments();  // z = 10, 12, 14
  spec.spacing_between_slices = 2.0;
  spec.frames.push_back({2, {-5, 7, 15.0}, test::box_pixels(spec, 2, 3, 3, 5)});
  const auto file = written(spec, "offgrid");
  try {
    read_seg(file);
    FAIL() << "a frame half a step off the grid was accepted";
  } catch (const SegError& error) {
    EXPECT_NE(std::string(error.what()).find("fit no slice grid"), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(read_seg_header(file), SegError);
}

TEST(SyntheticSeg, AShearedStackIsRefused) {
  SynthSeg spec = two_segments();
  spec.frames[2].position = {-5 + 3.0, 7, 14};  // moved in plane by 4 columns
  EXPECT_THROW(read_seg(written(spec, "sheared")), SegError);
}

TEST(SyntheticSeg, HeaderWithoutPixels) {
  SynthSeg spec = two_segments();
  spec.frames.push_back({2, {-5, 7, 16}, test::box_pixels(spec, 2, 3, 3, 5)});
  const SegHeader header = read_seg_header(written(spec, "header"));
  EXPECT_EQ(header.size, (core::VolumeSize{6, 4, 4}));
  EXPECT_EQ(header.segments.size(), 2u);
  EXPECT_EQ(header.layer_bytes(), 6u * 4u * 4u * 4u);
  EXPECT_EQ(header.kind, SegKind::binary);
}

TEST(SyntheticSeg, NothingIdentifyingLeavesTheReader) {
  SynthSeg spec = two_segments();
  spec.frames.push_back({2, {-5, 7, 12}, test::box_pixels(spec, 2, 3, 3, 5)});
  const auto file = written(spec, "privacy");
  ASSERT_NE(test::read_file_bytes(file).find("Doe^Jane"), std::string::npos);
  const SegVolume seg = read_seg(file);
  std::string text;
  for (const auto& s : seg.labels.segments) text += s.name + "\n";
  for (const auto& w : seg.warnings) text += w + "\n";
  for (const std::string& secret : {spec.patient_name, spec.patient_id, spec.content_creator,
                                    std::string("Doe"), std::string("Smith")}) {
    EXPECT_EQ(text.find(secret), std::string::npos) << secret;
  }
}

TEST(SyntheticSeg, RecognisedBySopClass) {
  const auto file = written(two_segments(), "kind");
  EXPECT_TRUE(is_seg_file(file));
  const auto other = file.parent_path() / "other.txt";
  std::ofstream(other) << "not dicom";
  EXPECT_FALSE(is_seg_file(other));
  EXPECT_FALSE(is_seg_file(file.parent_path() / "missing.dcm"));
}

}  // namespace
}  // namespace typemerge::seg
