#include "nifti/nifti_reader.h"

#include <nifti2_io.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "volume_file/file_bytes.h"

namespace typemerge::nifti {
namespace {

using volume_file::SampleType;

constexpr std::size_t kHeader1 = 348;
constexpr std::size_t kHeader2 = 540;

std::int32_t load_int32(const std::uint8_t* p) {
  std::int32_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

std::int32_t swapped(std::int32_t v) {
  std::uint32_t u;
  std::memcpy(&u, &v, sizeof u);
  u = __builtin_bswap32(u);
  std::memcpy(&v, &u, sizeof v);
  return v;
}

SampleType sample_type(int datatype) {
  switch (datatype) {
    case DT_INT8:
      return SampleType::int8;
    case DT_UINT8:
      return SampleType::uint8;
    case DT_INT16:
      return SampleType::int16;
    case DT_UINT16:
      return SampleType::uint16;
    case DT_INT32:
      return SampleType::int32;
    case DT_UINT32:
      return SampleType::uint32;
    case DT_INT64:
      return SampleType::int64;
    case DT_UINT64:
      return SampleType::uint64;
    case DT_FLOAT32:
      return SampleType::float32;
    case DT_FLOAT64:
      return SampleType::float64;
    default:
      break;
  }
  throw ReadError("NIfTI data type " + std::to_string(datatype) +
                  " is not supported (integer and real types are; complex, RGB and "
                  "float128 are not)");
}

// What the two header versions share, in the widths of NIfTI-2.
struct Fields {
  std::int64_t dim[8]{};
  double pixdim[8]{};
  int datatype = 0;
  double vox_offset = 0;
  double slope = 0, inter = 0;
  int qform_code = 0, sform_code = 0;
  int intent_code = 0;
  bool single_file = true;
};

struct NimDeleter {
  void operator()(nifti_image* nim) const { nifti_image_free(nim); }
};
using NimPtr = std::unique_ptr<nifti_image, NimDeleter>;

void quiet_nifticlib() {
  static const bool once = [] {
    nifti_set_debug_level(0);
    return true;
  }();
  (void)once;
}

bool finite_matrix(const nifti_dmat44& m) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!std::isfinite(m.m[r][c])) return false;
    }
  }
  return true;
}

// RAS matrix (rows x, y, z; columns i, j, k, offset) → LPS index-to-patient.
core::IndexToPatient to_lps(const nifti_dmat44& m) {
  core::IndexToPatient g;
  const double flip[3] = {-1, -1, 1};
  for (int r = 0; r < 3; ++r) {
    g.origin[r] = flip[r] * m.m[r][3];
    for (int a = 0; a < 3; ++a) g.axes[a][r] = flip[r] * m.m[r][a];
  }
  return g;
}

}  // namespace

std::uint64_t NiftiHeader::data_bytes() const {
  return static_cast<std::uint64_t>(size.voxels()) * volume_file::sample_bytes(type);
}

NiftiHeader parse_header(std::span<const std::uint8_t> bytes) {
  quiet_nifticlib();
  if (bytes.size() < kHeader1) {
    throw ReadError("not a NIfTI file: shorter than a NIfTI header (truncated?)");
  }
  const std::int32_t sizeof_hdr = load_int32(bytes.data());
  NiftiHeader header;
  Fields f;
  NimPtr nim;
  if (sizeof_hdr == 348 || swapped(sizeof_hdr) == 348) {
    header.version = 1;
    nifti_1_header h;
    std::memcpy(&h, bytes.data(), sizeof h);
    header.swap = sizeof_hdr != 348;
    if (header.swap) nifti_swap_as_nifti1(&h);
    if (std::memcmp(h.magic, "n+1", 4) != 0) {
      if (std::memcmp(h.magic, "ni1", 4) == 0) {
        throw ReadError("a NIfTI header/image pair (.hdr/.img): give a single-file .nii");
      }
      throw ReadError("not a NIfTI-1 file: bad magic (an Analyze 7.5 header?)");
    }
    for (int d = 0; d < 8; ++d) {
      f.dim[d] = h.dim[d];
      f.pixdim[d] = h.pixdim[d];
    }
    f.datatype = h.datatype;
    f.vox_offset = h.vox_offset;
    f.slope = h.scl_slope;
    f.inter = h.scl_inter;
    f.qform_code = h.qform_code;
    f.sform_code = h.sform_code;
    f.intent_code = h.intent_code;
    // The dimensions are checked below before nifticlib multiplies them.
    for (int d = 1; d <= 7; ++d) {
      if (d <= h.dim[0] && h.dim[d] < 1) h.dim[d] = 1;
    }
    // The data type is checked first: nifticlib prints its own complaint on stderr.
    header.type = sample_type(f.datatype);
    if (h.dim[0] >= 1 && h.dim[0] <= 7) nim.reset(nifti_convert_n1hdr2nim(h, nullptr));
  } else if (sizeof_hdr == 540 || swapped(sizeof_hdr) == 540) {
    header.version = 2;
    if (bytes.size() < kHeader2) {
      throw ReadError("not a NIfTI-2 file: shorter than its header (truncated?)");
    }
    nifti_2_header h;
    std::memcpy(&h, bytes.data(), sizeof h);
    header.swap = sizeof_hdr != 540;
    if (header.swap) nifti_swap_as_nifti2(&h);
    if (std::memcmp(h.magic, "n+2", 4) != 0) {
      if (std::memcmp(h.magic, "ni2", 4) == 0) {
        throw ReadError("a NIfTI header/image pair (.hdr/.img): give a single-file .nii");
      }
      throw ReadError("not a NIfTI-2 file: bad magic");
    }
    for (int d = 0; d < 8; ++d) {
      f.dim[d] = h.dim[d];
      f.pixdim[d] = h.pixdim[d];
    }
    f.datatype = h.datatype;
    f.vox_offset = static_cast<double>(h.vox_offset);
    f.slope = h.scl_slope;
    f.inter = h.scl_inter;
    f.qform_code = h.qform_code;
    f.sform_code = h.sform_code;
    f.intent_code = h.intent_code;
    // nifticlib multiplies the dimensions in int64: only valid ones reach it.
    bool dims_ok = h.dim[0] >= 1 && h.dim[0] <= 7;
    for (int d = 1; dims_ok && d <= h.dim[0]; ++d) dims_ok = h.dim[d] >= 1 && h.dim[d] <= (1 << 20);
    header.type = sample_type(f.datatype);  // before nifticlib, which prints on stderr
    if (dims_ok) nim.reset(nifti_convert_n2hdr2nim(h, nullptr));
  } else {
    throw ReadError("not a NIfTI file (its first four bytes are not a NIfTI header size)");
  }

  // Dimensions: 1..7 of them, each ≥ 1, at most three of extent > 1, product within int64.
  const std::int64_t ndim = f.dim[0];
  if (ndim < 1 || ndim > 7) {
    throw ReadError("NIfTI dim[0] is " + std::to_string(ndim) + ", not 1 to 7");
  }
  for (int d = 1; d <= ndim; ++d) {
    if (f.dim[d] < 1) {
      throw ReadError("NIfTI dimension " + std::to_string(d) + " is " + std::to_string(f.dim[d]) +
                      ", not ≥ 1");
    }
  }
  std::int64_t extent[3] = {1, 1, 1};
  for (int d = 1; d <= std::min<std::int64_t>(ndim, 3); ++d) extent[d - 1] = f.dim[d];
  std::int64_t more = 1;
  for (int d = 4; d <= ndim; ++d) {
    if (__builtin_mul_overflow(more, f.dim[d], &more))
      more = std::numeric_limits<std::int64_t>::max();
  }
  if (more > 1) {
    throw ReadError("a 4D NIfTI (" + std::to_string(more) +
                    " volumes): typemerge reads one 3D volume at a time; extract one first "
                    "(e.g. fslroi or nifti_tool -cbl)");
  }
  std::int64_t voxels = 1;
  for (std::int64_t e : extent) {
    if (__builtin_mul_overflow(voxels, e, &voxels)) {
      throw ReadError("NIfTI dimensions whose product overflows");
    }
  }
  std::int64_t data_bytes = 0;
  if (__builtin_mul_overflow(
          voxels, static_cast<std::int64_t>(volume_file::sample_bytes(header.type)), &data_bytes) ||
      data_bytes > (std::int64_t{1} << 48)) {
    throw ReadError("NIfTI dimensions whose product overflows");
  }
  header.size = {extent[0], extent[1], extent[2]};
  header.intent_label = f.intent_code == NIFTI_INTENT_LABEL;

  // Data offset: where the voxels start in a single file.
  const std::size_t header_bytes = header.version == 1 ? kHeader1 : kHeader2;
  if (!std::isfinite(f.vox_offset) || f.vox_offset < 0 || f.vox_offset > 9.0e15 ||
      f.vox_offset != std::floor(f.vox_offset)) {
    throw ReadError("NIfTI vox_offset is not a whole number of bytes");
  }
  header.data_offset = static_cast<std::uint64_t>(f.vox_offset);
  if (header.data_offset < header_bytes) {
    header.warnings.push_back("vox_offset " + std::to_string(header.data_offset) +
                              " lies inside the header; data read from byte " +
                              std::to_string(header_bytes + 4) +
                              " (after the header and its "
                              "extension flags)");
    header.data_offset = header_bytes + 4;
  }

  // Scaling: slope 0 (or not finite) means none.
  if (std::isfinite(f.slope) && f.slope != 0) {
    header.slope = f.slope;
    header.inter = std::isfinite(f.inter) ? f.inter : 0.0;
  }

  // Geometry.
  if (!nim) throw ReadError("NIfTI header rejected by nifticlib");
  if (f.sform_code > 0) {
    if (!finite_matrix(nim->sto_xyz)) throw ReadError("the NIfTI sform is not finite");
    header.geometry = to_lps(nim->sto_xyz);
    header.geometry_source = "sform";
  } else if (f.qform_code > 0) {
    if (!finite_matrix(nim->qto_xyz)) throw ReadError("the NIfTI qform is not finite");
    header.geometry = to_lps(nim->qto_xyz);
    header.geometry_source = "qform";
  } else {
    nifti_dmat44 m{};
    for (int a = 0; a < 3; ++a) {
      const double p = std::abs(f.pixdim[a + 1]);
      m.m[a][a] = std::isfinite(p) && p > 0 ? p : 1.0;
    }
    header.geometry = to_lps(m);
    header.geometry_source = "pixel spacing";
    header.warnings.push_back(
        "no sform or qform: voxels placed by their pixel spacing alone "
        "(orientation unknown, taken as RAS)");
  }
  const double det = header.geometry.determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12) {
    throw ReadError("the NIfTI " + header.geometry_source +
                    " is singular (a zero or parallel axis)");
  }
  return header;
}

NiftiHeader read_header(const std::filesystem::path& path) {
  try {
    return parse_header(volume_file::read_maybe_gzip(path, kHeader2));
  } catch (const volume_file::FileError& error) {
    throw ReadError(std::string("NIfTI: ") + error.what());
  }
}

NiftiImage decode_nifti(std::span<const std::uint8_t> file_bytes, const ReadOptions& options) {
  NiftiImage image;
  image.header = parse_header(file_bytes);
  const NiftiHeader& h = image.header;
  const std::uint64_t float_bytes = static_cast<std::uint64_t>(h.size.voxels()) * sizeof(float);
  if (float_bytes > options.max_volume_bytes) {
    throw ReadError("the NIfTI volume (" + std::to_string(h.size.nx) + "x" +
                    std::to_string(h.size.ny) + "x" + std::to_string(h.size.nz) +
                    ") is larger than the memory allowed for it");
  }
  if (h.data_offset >= file_bytes.size()) {
    throw ReadError("NIfTI vox_offset lies beyond the end of the file");
  }
  if (file_bytes.size() - h.data_offset < h.data_bytes()) {
    throw ReadError("the NIfTI file is truncated: its data needs " +
                    std::to_string(h.data_bytes()) + " bytes after vox_offset, it holds " +
                    std::to_string(file_bytes.size() - h.data_offset));
  }
  const auto data = file_bytes.subspan(static_cast<std::size_t>(h.data_offset));
  const auto voxels = static_cast<std::size_t>(h.size.voxels());
  if (volume_file::fits_int16(data, h.type, h.swap, 0, 1, voxels, h.slope, h.inter)) {
    image.volume = core::Volume::uninitialized(h.size, h.geometry, core::SampleType::int16);
    image.values = volume_file::decode_samples(data, h.type, h.swap, 0, 1, voxels, h.slope,
                                               h.inter, image.volume.int16_samples().data());
  } else {
    image.volume = core::Volume::uninitialized(h.size, h.geometry);
    image.values = volume_file::decode_samples(data, h.type, h.swap, 0, 1, voxels, h.slope,
                                               h.inter, image.volume.samples().data());
  }
  image.warnings = h.warnings;
  if (image.values.non_finite > 0) {
    image.warnings.push_back(std::to_string(image.values.non_finite) +
                             " non-finite value(s) (NaN or infinite) read as 0");
  }
  return image;
}

namespace {

// `total` over consecutive runs of samples, `part` the next run's.
void merge(volume_file::DecodeSummary& total, const volume_file::DecodeSummary& part,
           bool first) {
  if (first) {
    total = part;
    return;
  }
  total.non_finite += part.non_finite;
  total.all_integer = total.all_integer && part.all_integer;
  total.min = std::min(total.min, part.min);
  total.max = std::max(total.max, part.max);
}

// The file's data decoded into the volume as it is read (inflated), in pieces, so that the
// (inflated) file is never held whole. Storage: `decided` (int16_by_type), or where the values
// decide, int16 until a piece holds a value beyond it, then float from there on (the samples
// so far converted). The same volume, summary, warnings and refusals as decode_nifti.
NiftiImage stream_nifti(const std::filesystem::path& path, const NiftiHeader& h,
                        std::optional<bool> decided) {
  bool int16 = decided.value_or(true);
  NiftiImage image;
  image.header = h;
  const auto voxels = static_cast<std::size_t>(h.size.voxels());
  const std::size_t bytes_per_sample = volume_file::sample_bytes(h.type);
  image.volume = core::Volume::uninitialized(
      h.size, h.geometry, int16 ? core::SampleType::int16 : core::SampleType::float32);
  std::vector<std::uint8_t> carry;  // a sample cut between two pieces
  std::uint64_t seen = 0;           // file bytes so far
  std::size_t done = 0;             // samples decoded
  auto decode = [&](std::span<const std::uint8_t> bytes, std::size_t count) {
    if (int16 && !decided.has_value() &&
        !volume_file::fits_int16(bytes, h.type, h.swap, 0, 1, count, h.slope, h.inter)) {
      core::Volume as_float = core::Volume::uninitialized(h.size, h.geometry);
      const std::int16_t* from = image.volume.int16_samples().data();
      std::copy(from, from + done, as_float.samples().data());
      image.volume = std::move(as_float);
      int16 = false;
    }
    const auto part =
        int16 ? volume_file::decode_samples(bytes, h.type, h.swap, 0, 1, count, h.slope, h.inter,
                                            image.volume.int16_samples().data() + done)
              : volume_file::decode_samples(bytes, h.type, h.swap, 0, 1, count, h.slope, h.inter,
                                            image.volume.samples().data() + done);
    merge(image.values, part, done == 0);
    done += count;
  };
  auto sink = [&](std::span<const std::uint8_t> piece) {
    const std::uint64_t start = seen;
    seen += piece.size();
    if (seen <= h.data_offset || done == voxels) return;
    if (start < h.data_offset) piece = piece.subspan(static_cast<std::size_t>(h.data_offset - start));
    if (!carry.empty()) {
      const std::size_t take = std::min(bytes_per_sample - carry.size(), piece.size());
      carry.insert(carry.end(), piece.begin(), piece.begin() + static_cast<std::ptrdiff_t>(take));
      piece = piece.subspan(take);
      if (carry.size() < bytes_per_sample) return;
      decode(carry, 1);
      carry.clear();
    }
    const std::size_t count = std::min(piece.size() / bytes_per_sample, voxels - done);
    if (count > 0) decode(piece.first(count * bytes_per_sample), count);
    if (done < voxels) carry.assign(piece.begin() + static_cast<std::ptrdiff_t>(count * bytes_per_sample), piece.end());
  };
  const std::uint64_t need = h.data_offset + h.data_bytes();
  const volume_file::Bytes head = volume_file::read_file(path, 2);
  if (volume_file::is_gzip(head)) {
    volume_file::gunzip_file_into(path, static_cast<std::size_t>(need), sink);
  } else {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw volume_file::FileError("cannot open the file");
    std::vector<std::uint8_t> piece(std::size_t{1} << 20);
    while (seen < need && in) {
      const auto want = static_cast<std::streamsize>(
          std::min<std::uint64_t>(piece.size(), need - seen));
      in.read(reinterpret_cast<char*>(piece.data()), want);
      const auto got = static_cast<std::size_t>(in.gcount());
      if (got == 0) break;
      sink(std::span<const std::uint8_t>(piece.data(), got));
    }
  }
  if (seen <= h.data_offset) throw ReadError("NIfTI vox_offset lies beyond the end of the file");
  if (done < voxels) {
    throw ReadError("the NIfTI file is truncated: its data needs " +
                    std::to_string(h.data_bytes()) + " bytes after vox_offset, it holds " +
                    std::to_string(seen - h.data_offset));
  }
  image.warnings = h.warnings;
  if (image.values.non_finite > 0) {
    image.warnings.push_back(std::to_string(image.values.non_finite) +
                             " non-finite value(s) (NaN or infinite) read as 0");
  }
  return image;
}

}  // namespace

NiftiImage read_nifti(const std::filesystem::path& path, const ReadOptions& options) {
  const NiftiHeader header = read_header(path);
  const std::uint64_t float_bytes =
      static_cast<std::uint64_t>(header.size.voxels()) * sizeof(float);
  if (float_bytes > options.max_volume_bytes) {
    throw ReadError("the NIfTI volume (" + std::to_string(header.size.nx) + "x" +
                    std::to_string(header.size.ny) + "x" + std::to_string(header.size.nz) +
                    ") is larger than the memory allowed for it");
  }
  try {
    // The data is decoded as it is read (stream_nifti), never held whole.
    return stream_nifti(path, header,
                        volume_file::int16_by_type(header.type, header.slope, header.inter));
  } catch (const volume_file::FileError& error) {
    throw ReadError(std::string("NIfTI: ") + error.what());
  }
}

}  // namespace typemerge::nifti
