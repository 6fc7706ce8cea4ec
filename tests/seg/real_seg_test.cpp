// The dcmqi SEGs in the shared data against their NRRD label maps (read here by a minimal
// parser of the few fields they use, independent of the project's NRRD reader), and the liver
// SEG against its CT's slice positions (read with DCMTK directly).
#include <gtest/gtest.h>
#include <zlib.h>

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <map>
#include <sstream>

#include "seg/seg_reader.h"
#include "support/scratch_files.h"
#include "support/test_data.h"

namespace typemerge::seg {
namespace {

struct NrrdLabels {
  std::array<std::int64_t, 3> sizes{};
  std::array<core::Vec3, 3> directions{};
  core::Vec3 origin{};
  std::vector<std::int16_t> values;  // x fastest

  std::int16_t at(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return values[static_cast<std::size_t>(i + sizes[0] * (j + sizes[1] * k))];
  }
};

core::Vec3 parse_vector(const std::string& text) {  // "(a,b,c)"
  core::Vec3 v{};
  std::string inner = text.substr(text.find('(') + 1);
  std::replace(inner.begin(), inner.end(), ',', ' ');
  std::istringstream in(inner);
  in >> v[0] >> v[1] >> v[2];
  return v;
}

// Little-endian int16 3D NRRD, raw or gzip, with space directions and origin.
NrrdLabels read_nrrd_labels(const std::filesystem::path& file) {
  const std::string bytes = test::read_file_bytes(file);
  const std::size_t end = bytes.find("\n\n");
  if (end == std::string::npos) throw std::runtime_error("no NRRD header end");
  std::istringstream header(bytes.substr(0, end));
  NrrdLabels nrrd;
  std::string line, encoding;
  while (std::getline(header, line)) {
    const std::size_t colon = line.find(": ");
    if (line.empty() || line[0] == '#' || colon == std::string::npos) continue;
    const std::string key = line.substr(0, colon), value = line.substr(colon + 2);
    if (key == "type" && value != "short") throw std::runtime_error("type " + value);
    if (key == "endian" && value != "little") throw std::runtime_error("big endian");
    if (key == "encoding") encoding = value;
    if (key == "sizes") {
      std::istringstream in(value);
      in >> nrrd.sizes[0] >> nrrd.sizes[1] >> nrrd.sizes[2];
    }
    if (key == "space directions") {
      std::istringstream in(value);
      std::string part;
      for (auto& d : nrrd.directions) {
        in >> part;
        d = parse_vector(part);
      }
    }
    if (key == "space origin") nrrd.origin = parse_vector(value);
    if (key == "space" && value != "left-posterior-superior") throw std::runtime_error(value);
  }
  std::string data = bytes.substr(end + 2);
  const std::size_t count = static_cast<std::size_t>(nrrd.sizes[0] * nrrd.sizes[1] * nrrd.sizes[2]);
  std::string raw(count * 2, '\0');
  if (encoding == "gzip" || encoding == "gz") {
    z_stream stream{};
    inflateInit2(&stream, 16 + MAX_WBITS);
    stream.next_in = reinterpret_cast<Bytef*>(data.data());
    stream.avail_in = static_cast<uInt>(data.size());
    stream.next_out = reinterpret_cast<Bytef*>(raw.data());
    stream.avail_out = static_cast<uInt>(raw.size());
    const int status = inflate(&stream, Z_FINISH);
    inflateEnd(&stream);
    if (status != Z_STREAM_END) throw std::runtime_error("gzip");
  } else {
    raw = data.substr(0, count * 2);
  }
  nrrd.values.resize(count);
  std::memcpy(nrrd.values.data(), raw.data(), count * 2);
  return nrrd;
}

// LPS point → the NRRD's (continuous) index, by solving origin + [directions]·ijk = p.
core::Vec3 nrrd_index(const NrrdLabels& nrrd, const core::Vec3& p) {
  const auto& d = nrrd.directions;
  const core::Vec3 q = {p[0] - nrrd.origin[0], p[1] - nrrd.origin[1], p[2] - nrrd.origin[2]};
  auto det3 = [](const core::Vec3& a, const core::Vec3& b, const core::Vec3& c) {
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
           a[2] * (b[0] * c[1] - b[1] * c[0]);
  };
  const double det = det3(d[0], d[1], d[2]);  // columns are the directions (Cramer's rule)
  return {det3(q, d[1], d[2]) / det, det3(d[0], q, d[2]) / det, det3(d[0], d[1], q) / det};
}

void expect_seg_matches_nrrd(const std::filesystem::path& case_dir) {
  const SegVolume seg = read_seg(case_dir / "seg" / "label.seg");
  const NrrdLabels nrrd = read_nrrd_labels(case_dir / "nrrd" / "label.nrrd");
  ASSERT_EQ(seg.labels.layers.size(), 1u);
  ASSERT_EQ(seg.labels.segments.size(), 1u);
  EXPECT_EQ(seg.labels.segments[0].name, "Liver");
  const core::Volume& layer = seg.labels.layers[0];
  EXPECT_EQ(layer.size(), (core::VolumeSize{nrrd.sizes[0], nrrd.sizes[1], nrrd.sizes[2]}));

  // Every SEG voxel lands on an NRRD voxel centre with the same inside/outside.
  std::int64_t inside = 0, mismatches = 0;
  const core::VolumeSize size = layer.size();
  for (std::int64_t k = 0; k < size.nz; ++k) {
    for (std::int64_t j = 0; j < size.ny; ++j) {
      for (std::int64_t i = 0; i < size.nx; ++i) {
        const core::Vec3 n = nrrd_index(nrrd, layer.geometry().apply(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)));
        const std::array<std::int64_t, 3> m = {std::llround(n[0]), std::llround(n[1]),
                                               std::llround(n[2])};
        for (int a = 0; a < 3; ++a) {
          ASSERT_NEAR(n[a], static_cast<double>(m[a]), 1e-3);
          ASSERT_GE(m[a], 0);
          ASSERT_LT(m[a], nrrd.sizes[a]);
        }
        const bool seg_inside = layer.at(i, j, k) != 0.0f;
        const bool nrrd_inside = nrrd.at(m[0], m[1], m[2]) != 0;
        inside += seg_inside ? 1 : 0;
        mismatches += seg_inside != nrrd_inside ? 1 : 0;
      }
    }
  }
  EXPECT_GT(inside, 0);
  EXPECT_EQ(mismatches, 0) << "of " << inside << " inside voxels";
}

TEST(RealSeg, OddColumnsMatchTheirNrrdLabelMap) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  expect_seg_matches_nrrd(data / "seg" / "dcmqi" / "23x38x3");
}

TEST(RealSeg, EvenColumnsMatchTheirNrrdLabelMap) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  expect_seg_matches_nrrd(data / "seg" / "dcmqi" / "24x38x3");
}

TEST(RealSeg, LiverFramesLandOnTheCtSlices) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const auto dir = data / "seg" / "dcmqi";
  const SegVolume seg = read_seg(dir / "liver.dcm");
  ASSERT_EQ(seg.labels.layers.size(), 1u);
  ASSERT_EQ(seg.labels.segments.size(), 1u);
  EXPECT_TRUE(seg.labels.segments[0].srgb.has_value());
  const core::Volume& layer = seg.labels.layers[0];

  // The CT's slices, from their own headers.
  std::vector<core::Vec3> ct_positions;
  Uint16 rows = 0, columns = 0;
  for (const char* name : {"01.dcm", "02.dcm", "03.dcm"}) {
    DcmFileFormat format;
    ASSERT_TRUE(format.loadFile((dir / "ct-3slice" / name).c_str()).good());
    core::Vec3 p{};
    for (unsigned long a = 0; a < 3; ++a) {
      ASSERT_TRUE(format.getDataset()->findAndGetFloat64(DCM_ImagePositionPatient, p[a], a).good());
    }
    format.getDataset()->findAndGetUint16(DCM_Rows, rows);
    format.getDataset()->findAndGetUint16(DCM_Columns, columns);
    ct_positions.push_back(p);
  }
  EXPECT_EQ(layer.size().nx, columns);
  EXPECT_EQ(layer.size().ny, rows);
  ASSERT_EQ(layer.size().nz, 3);
  // Each CT slice's first pixel is one of the SEG's slice origins, and each SEG slice is a CT's.
  for (std::int64_t k = 0; k < 3; ++k) {
    const core::Vec3 p = layer.geometry().apply(0, 0, static_cast<double>(k));
    double nearest = 1e9;
    for (const auto& c : ct_positions) {
      nearest = std::min(nearest, std::hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]));
    }
    EXPECT_LT(nearest, 0.01) << "slice " << k;
  }
  std::int64_t inside = 0;
  for (float v : layer.samples()) inside += v != 0.0f ? 1 : 0;
  EXPECT_GT(inside, 1000);
}

TEST(RealSeg, HeaderOfTheLiver) {
  TYPEMERGE_REQUIRE_REAL_DATA(data);
  const SegHeader header = read_seg_header(data / "seg" / "dcmqi" / "liver.dcm");
  EXPECT_EQ(header.size, (core::VolumeSize{512, 512, 3}));
  EXPECT_EQ(header.segments.size(), 1u);
  EXPECT_EQ(header.frame_slice.size(), 3u);
}

}  // namespace
}  // namespace typemerge::seg
