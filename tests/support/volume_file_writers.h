// Writers of small NIfTI-1/2 and NRRD files for the reader and label-mode tests, written from
// the formats' specifications byte by byte (not with the readers' libraries), so that they
// check the readers independently.
#pragma once

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace typemerge::test {

using FileBytes = std::vector<std::uint8_t>;

inline void write_bytes(const std::filesystem::path& path, const FileBytes& bytes, bool gzip) {
  if (gzip) {
    gzFile file = gzopen(path.c_str(), "wb");
    if (file == nullptr) throw std::runtime_error("cannot write " + path.string());
    gzwrite(file, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(file);
    return;
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

inline FileBytes gzip_bytes(const FileBytes& raw) {
  uLongf size = compressBound(static_cast<uLong>(raw.size())) + 64;
  FileBytes out(size);
  z_stream s{};
  deflateInit2(&s, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  s.next_in = const_cast<Bytef*>(raw.data());
  s.avail_in = static_cast<uInt>(raw.size());
  s.next_out = out.data();
  s.avail_out = static_cast<uInt>(out.size());
  deflate(&s, Z_FINISH);
  out.resize(s.total_out);
  deflateEnd(&s);
  return out;
}

class ByteWriter {
 public:
  explicit ByteWriter(std::size_t size, bool big_endian = false) : bytes_(size), big_(big_endian) {}
  template <typename T>
  void put(std::size_t offset, T value) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &value, sizeof(T));
    if (big_) std::reverse(b, b + sizeof(T));
    if (offset + sizeof(T) > bytes_.size()) bytes_.resize(offset + sizeof(T));
    std::memcpy(bytes_.data() + offset, b, sizeof(T));
  }
  void text(std::size_t offset, const std::string& s, std::size_t max) {
    for (std::size_t i = 0; i < std::min(s.size(), max); ++i)
      bytes_[offset + i] = static_cast<std::uint8_t>(s[i]);
  }
  template <typename T>
  void append_values(const std::vector<double>& values) {
    for (double v : values) put<T>(bytes_.size(), static_cast<T>(v));
  }
  FileBytes& bytes() { return bytes_; }

 private:
  FileBytes bytes_;
  bool big_;
};

// NIfTI datatype codes.
enum NiftiType : int {
  kDtUint8 = 2,
  kDtInt16 = 4,
  kDtInt32 = 8,
  kDtFloat32 = 16,
  kDtFloat64 = 64,
  kDtInt8 = 256,
  kDtUint16 = 512,
  kDtUint32 = 768,
  kDtInt64 = 1024,
  kDtUint64 = 1280,
  kDtComplex64 = 32
};

struct NiftiSpec {
  int version = 1;
  std::array<std::int64_t, 8> dim{3, 1, 1, 1, 1, 1, 1, 1};
  int datatype = kDtFloat32;
  std::vector<double> values;  // stored values, x fastest
  double slope = 0, inter = 0;
  int qform_code = 0, sform_code = 1;
  std::array<std::array<double, 4>, 3> srow{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};  // RAS
  std::array<double, 3> quatern{0, 0, 0};
  std::array<double, 3> qoffset{0, 0, 0};
  double qfac = 1;
  std::array<double, 3> pixdim{1, 1, 1};
  std::string descrip, aux_file, intent_name, db_name, extension;
  int intent_code = 0;
  bool big_endian = false;
  std::int64_t vox_offset = -1;  // -1: right after the header (and extension)
};

template <typename T>
void append_as(ByteWriter& w, const std::vector<double>& values) {
  w.append_values<T>(values);
}

inline FileBytes nifti_bytes(const NiftiSpec& s) {
  const bool v1 = s.version == 1;
  const std::size_t header = v1 ? 348 : 540;
  ByteWriter w(header + 4, s.big_endian);
  std::size_t ext_size = 0;
  if (!s.extension.empty()) ext_size = (8 + s.extension.size() + 15) / 16 * 16;
  const std::int64_t offset =
      s.vox_offset >= 0 ? s.vox_offset : std::int64_t(header + 4 + ext_size);
  int bitpix = 8;
  switch (s.datatype) {
    case kDtInt16:
    case kDtUint16:
      bitpix = 16;
      break;
    case kDtInt32:
    case kDtUint32:
    case kDtFloat32:
      bitpix = 32;
      break;
    case kDtInt64:
    case kDtUint64:
    case kDtFloat64:
    case kDtComplex64:
      bitpix = 64;
      break;
    default:
      break;
  }
  if (v1) {
    w.put<std::int32_t>(0, 348);
    w.text(14, s.db_name, 18);
    for (int d = 0; d < 8; ++d)
      w.put<std::int16_t>(40 + 2 * d, static_cast<std::int16_t>(s.dim[d]));
    w.put<std::int16_t>(68, static_cast<std::int16_t>(s.intent_code));
    w.put<std::int16_t>(70, static_cast<std::int16_t>(s.datatype));
    w.put<std::int16_t>(72, static_cast<std::int16_t>(bitpix));
    w.put<float>(76, static_cast<float>(s.qfac));
    for (int d = 0; d < 3; ++d) w.put<float>(80 + 4 * d, static_cast<float>(s.pixdim[d]));
    w.put<float>(108, static_cast<float>(offset));
    w.put<float>(112, static_cast<float>(s.slope));
    w.put<float>(116, static_cast<float>(s.inter));
    w.text(148, s.descrip, 80);
    w.text(228, s.aux_file, 24);
    w.put<std::int16_t>(252, static_cast<std::int16_t>(s.qform_code));
    w.put<std::int16_t>(254, static_cast<std::int16_t>(s.sform_code));
    for (int c = 0; c < 3; ++c) w.put<float>(256 + 4 * c, static_cast<float>(s.quatern[c]));
    for (int c = 0; c < 3; ++c) w.put<float>(268 + 4 * c, static_cast<float>(s.qoffset[c]));
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c)
        w.put<float>(280 + 16 * r + 4 * c, static_cast<float>(s.srow[r][c]));
    }
    w.text(328, s.intent_name, 16);
    w.text(344, std::string("n+1\0", 4), 4);
  } else {
    w.put<std::int32_t>(0, 540);
    w.text(4, std::string("n+2\0\r\n\032\n", 8), 8);
    w.put<std::int16_t>(12, static_cast<std::int16_t>(s.datatype));
    w.put<std::int16_t>(14, static_cast<std::int16_t>(bitpix));
    for (int d = 0; d < 8; ++d) w.put<std::int64_t>(16 + 8 * d, s.dim[d]);
    w.put<double>(104, s.qfac);
    for (int d = 0; d < 3; ++d) w.put<double>(112 + 8 * d, s.pixdim[d]);
    w.put<std::int64_t>(168, offset);
    w.put<double>(176, s.slope);
    w.put<double>(184, s.inter);
    w.text(240, s.descrip, 80);
    w.text(320, s.aux_file, 24);
    w.put<std::int32_t>(344, s.qform_code);
    w.put<std::int32_t>(348, s.sform_code);
    for (int c = 0; c < 3; ++c) w.put<double>(352 + 8 * c, s.quatern[c]);
    for (int c = 0; c < 3; ++c) w.put<double>(376 + 8 * c, s.qoffset[c]);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) w.put<double>(400 + 32 * r + 8 * c, s.srow[r][c]);
    }
    w.put<std::int32_t>(504, s.intent_code);
    w.text(508, s.intent_name, 16);
  }
  if (ext_size > 0) {
    w.put<std::uint8_t>(header, 1);
    w.put<std::int32_t>(header + 4, static_cast<std::int32_t>(ext_size));
    w.put<std::int32_t>(header + 8, 6);  // NIFTI_ECODE_COMMENT
    w.bytes().resize(header + 4 + ext_size, 0);
    w.text(header + 12, s.extension, ext_size - 8);
  }
  if (offset >= 0 && static_cast<std::size_t>(offset) > w.bytes().size())
    w.bytes().resize(static_cast<std::size_t>(offset), 0);
  switch (s.datatype) {
    case kDtUint8:
      append_as<std::uint8_t>(w, s.values);
      break;
    case kDtInt8:
      append_as<std::int8_t>(w, s.values);
      break;
    case kDtInt16:
      append_as<std::int16_t>(w, s.values);
      break;
    case kDtUint16:
      append_as<std::uint16_t>(w, s.values);
      break;
    case kDtInt32:
      append_as<std::int32_t>(w, s.values);
      break;
    case kDtUint32:
      append_as<std::uint32_t>(w, s.values);
      break;
    case kDtInt64:
      append_as<std::int64_t>(w, s.values);
      break;
    case kDtUint64:
      append_as<std::uint64_t>(w, s.values);
      break;
    case kDtFloat64:
      append_as<double>(w, s.values);
      break;
    default:
      append_as<float>(w, s.values);
      break;
  }
  return w.bytes();
}

inline void write_nifti(const std::filesystem::path& path, const NiftiSpec& spec) {
  write_bytes(path, nifti_bytes(spec), path.extension() == ".gz");
}

// Raw little-endian samples of type T.
template <typename T>
FileBytes raw_samples(const std::vector<double>& values, bool big_endian = false) {
  ByteWriter w(0, big_endian);
  w.append_values<T>(values);
  return w.bytes();
}

// A .nrrd: `header` (lines, each ending in \n, without the magic and the blank line) then the
// data, gzip-compressed when `gzip` (the header must say encoding: gzip).
inline FileBytes nrrd_bytes(const std::string& header, const FileBytes& data, bool gzip) {
  const std::string text = "NRRD0004\n" + header + "\n";
  FileBytes out(text.begin(), text.end());
  const FileBytes payload = gzip ? gzip_bytes(data) : data;
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

}  // namespace typemerge::test
