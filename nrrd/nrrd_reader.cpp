#include "nrrd/nrrd_reader.h"

#include <algorithm>
#include <bit>
#include <string>
#include <string_view>

#include "volume_file/file_bytes.h"

namespace typemerge::nrrd {
namespace {

constexpr std::size_t kMaxHeaderBytes = std::size_t{4} << 20;

void check_memory(const NrrdHeader& header, const ReadOptions& options) {
  if (header.samples() * sizeof(float) > options.max_volume_bytes) {
    throw ReadError("the NRRD volume (" + std::to_string(header.size.nx) + "x" +
                    std::to_string(header.size.ny) + "x" + std::to_string(header.size.nz) +
                    (header.layers > 1 ? ", " + std::to_string(header.layers) + " layers" : "") +
                    ") is larger than the memory allowed for it");
  }
}

std::string_view as_text(std::span<const std::uint8_t> bytes) {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

}  // namespace

NrrdImage decode_nrrd_data(NrrdHeader header, std::span<const std::uint8_t> data,
                           const ReadOptions& options) {
  check_memory(header, options);
  for (std::int64_t line = 0; line < header.line_skip; ++line) {
    const auto newline = std::find(data.begin(), data.end(), std::uint8_t{'\n'});
    if (newline == data.end()) throw ReadError("the NRRD data is shorter than its line skip");
    data = data.subspan(static_cast<std::size_t>(newline - data.begin()) + 1);
  }
  const std::uint64_t need = header.data_bytes();
  volume_file::Bytes inflated;
  if (header.encoding == Encoding::gzip) {
    try {
      inflated = volume_file::gunzip(
          data, static_cast<std::size_t>(need + static_cast<std::uint64_t>(header.byte_skip)));
    } catch (const volume_file::FileError& error) {
      throw ReadError(std::string("NRRD data: ") + error.what());
    }
    data = inflated;
  }
  if (header.byte_skip == -1) {
    if (data.size() < need) throw ReadError("the NRRD data is truncated");
    data = data.subspan(data.size() - static_cast<std::size_t>(need));
  } else {
    if (static_cast<std::uint64_t>(header.byte_skip) > data.size()) {
      throw ReadError("the NRRD byte skip lies beyond the data");
    }
    data = data.subspan(static_cast<std::size_t>(header.byte_skip));
  }
  if (data.size() < need) {
    throw ReadError("the NRRD data is truncated: " + std::to_string(data.size()) + " of " +
                    std::to_string(need) + " bytes");
  }

  NrrdImage image;
  const bool swap = header.big_endian != (std::endian::native == std::endian::big) &&
                    volume_file::sample_bytes(header.type) > 1;
  const auto voxels = static_cast<std::size_t>(header.size.voxels());
  const std::size_t layers = header.layers;
  bool first = true;
  for (std::size_t l = 0; l < layers; ++l) {
    const std::size_t start = header.layer_axis_first ? l : l * voxels;
    const std::size_t stride = header.layer_axis_first ? layers : 1;
    const bool int16 =
        volume_file::fits_int16(data, header.type, swap, start, stride, voxels, 1.0, 0.0);
    core::Volume volume = core::Volume::uninitialized(
        header.size, header.geometry, int16 ? core::SampleType::int16 : core::SampleType::float32);
    const auto summary =
        int16 ? volume_file::decode_samples(data, header.type, swap, start, stride, voxels, 1.0,
                                            0.0, volume.int16_samples().data())
              : volume_file::decode_samples(data, header.type, swap, start, stride, voxels, 1.0,
                                            0.0, volume.samples().data());
    if (first) {
      image.values = summary;
      first = false;
    } else {
      image.values.non_finite += summary.non_finite;
      image.values.all_integer = image.values.all_integer && summary.all_integer;
      image.values.min = std::min(image.values.min, summary.min);
      image.values.max = std::max(image.values.max, summary.max);
    }
    image.layers.push_back(std::move(volume));
  }
  image.warnings = header.warnings;
  if (image.values.non_finite > 0) {
    image.warnings.push_back(std::to_string(image.values.non_finite) +
                             " non-finite value(s) (NaN or infinite) read as 0");
  }
  image.header = std::move(header);
  return image;
}

NrrdImage decode_nrrd(std::span<const std::uint8_t> file_bytes, const ReadOptions& options) {
  NrrdHeader header = parse_nrrd_header(as_text(file_bytes));
  if (!header.data_file.empty()) throw ReadError("a detached NRRD header needs its data file");
  const std::size_t offset = header.header_bytes;
  return decode_nrrd_data(std::move(header), file_bytes.subspan(offset), options);
}

NrrdHeader read_nrrd_header(const std::filesystem::path& path) {
  try {
    const volume_file::Bytes head = volume_file::read_file(path, kMaxHeaderBytes);
    return parse_nrrd_header(as_text(head));
  } catch (const volume_file::FileError& error) {
    throw ReadError(std::string("NRRD: ") + error.what());
  }
}

NrrdImage read_nrrd(const std::filesystem::path& path, const ReadOptions& options) {
  NrrdHeader header = read_nrrd_header(path);
  check_memory(header, options);
  try {
    if (header.data_file.empty()) {
      const volume_file::Bytes bytes = volume_file::read_file(path);
      const std::size_t offset = header.header_bytes;
      return decode_nrrd_data(std::move(header), std::span(bytes).subspan(offset), options);
    }
    std::filesystem::path data_path = header.data_file;
    if (data_path.is_relative()) data_path = path.parent_path() / data_path;
    const volume_file::Bytes bytes = volume_file::read_file(data_path);
    return decode_nrrd_data(std::move(header), bytes, options);
  } catch (const volume_file::FileError& error) {
    throw ReadError(std::string("NRRD data file: ") + error.what());
  }
}

core::LabelVolume to_label_volume(NrrdImage&& image) {
  core::LabelVolume labels;
  labels.layers = std::move(image.layers);
  labels.segments = std::move(image.header.segments);
  return labels;
}

}  // namespace typemerge::nrrd
