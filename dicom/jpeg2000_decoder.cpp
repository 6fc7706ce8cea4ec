#include "dicom/jpeg2000_decoder.h"

#include <openjpeg.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace typemerge::dicom {
namespace {

struct MemoryStream {
  const std::uint8_t* data;
  std::size_t size;
  std::size_t pos;
};

OPJ_SIZE_T read_memory(void* buffer, OPJ_SIZE_T bytes, void* user) {
  auto* stream = static_cast<MemoryStream*>(user);
  if (stream->pos >= stream->size) return static_cast<OPJ_SIZE_T>(-1);
  const std::size_t n = std::min<std::size_t>(bytes, stream->size - stream->pos);
  std::memcpy(buffer, stream->data + stream->pos, n);
  stream->pos += n;
  return n;
}

OPJ_OFF_T skip_memory(OPJ_OFF_T bytes, void* user) {
  auto* stream = static_cast<MemoryStream*>(user);
  const auto target = static_cast<long long>(stream->pos) + bytes;
  stream->pos = static_cast<std::size_t>(std::clamp<long long>(target, 0, stream->size));
  return bytes;
}

OPJ_BOOL seek_memory(OPJ_OFF_T to, void* user) {
  auto* stream = static_cast<MemoryStream*>(user);
  if (to < 0 || static_cast<std::size_t>(to) > stream->size) return OPJ_FALSE;
  stream->pos = static_cast<std::size_t>(to);
  return OPJ_TRUE;
}

void remember_error(const char* message, void* user) {
  auto* last = static_cast<std::string*>(user);
  *last = message;
  while (!last->empty() && last->back() == '\n') last->pop_back();
}
void ignore_message(const char*, void*) {}

}  // namespace

DecodedJpeg2000 decode_jpeg2000(const std::uint8_t* data, std::size_t size) {
  static const std::uint8_t kJp2Signature[] = {0x00, 0x00, 0x00, 0x0C, 0x6A, 0x50, 0x20, 0x20};
  const bool jp2 = size >= sizeof kJp2Signature &&
                   std::memcmp(data, kJp2Signature, sizeof kJp2Signature) == 0;
  std::unique_ptr<opj_codec_t, decltype(&opj_destroy_codec)> codec(
      opj_create_decompress(jp2 ? OPJ_CODEC_JP2 : OPJ_CODEC_J2K), &opj_destroy_codec);
  std::string last_error;
  opj_set_error_handler(codec.get(), remember_error, &last_error);
  opj_set_warning_handler(codec.get(), ignore_message, nullptr);
  opj_set_info_handler(codec.get(), ignore_message, nullptr);
  opj_dparameters_t parameters;
  opj_set_default_decoder_parameters(&parameters);
  if (!opj_setup_decoder(codec.get(), &parameters)) throw std::runtime_error("JPEG 2000 setup");

  MemoryStream memory{data, size, 0};
  std::unique_ptr<opj_stream_t, decltype(&opj_stream_destroy)> stream(
      opj_stream_create(1 << 16, OPJ_TRUE), &opj_stream_destroy);
  opj_stream_set_user_data(stream.get(), &memory, nullptr);
  opj_stream_set_user_data_length(stream.get(), size);
  opj_stream_set_read_function(stream.get(), read_memory);
  opj_stream_set_skip_function(stream.get(), skip_memory);
  opj_stream_set_seek_function(stream.get(), seek_memory);

  opj_image_t* raw_image = nullptr;
  if (!opj_read_header(stream.get(), codec.get(), &raw_image)) {
    throw std::runtime_error("JPEG 2000 header: " + last_error);
  }
  std::unique_ptr<opj_image_t, decltype(&opj_image_destroy)> image(raw_image, &opj_image_destroy);
  if (!opj_decode(codec.get(), stream.get(), image.get()) ||
      !opj_end_decompress(codec.get(), stream.get())) {
    throw std::runtime_error("JPEG 2000 decoding: " + last_error);
  }
  if (image->numcomps != 1) {
    throw std::runtime_error("JPEG 2000 frame has " + std::to_string(image->numcomps) +
                             " components, expected 1");
  }
  const opj_image_comp_t& component = image->comps[0];
  DecodedJpeg2000 decoded;
  decoded.width = component.w;
  decoded.height = component.h;
  decoded.is_signed = component.sgnd != 0;
  decoded.precision = component.prec;
  decoded.samples.assign(component.data,
                         component.data + std::size_t{component.w} * component.h);
  return decoded;
}

}  // namespace typemerge::dicom
