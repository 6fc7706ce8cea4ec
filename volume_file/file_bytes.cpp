#include "volume_file/file_bytes.h"

#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <limits>
#include <string>

namespace typemerge::volume_file {

Bytes read_file(const std::filesystem::path& path, std::size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError("cannot open the file");
  std::error_code error;
  const auto size = std::filesystem::file_size(path, error);
  if (error) throw FileError("cannot read the file's size");
  const std::size_t wanted = static_cast<std::size_t>(std::min<std::uintmax_t>(size, max_bytes));
  Bytes bytes(wanted);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(wanted));
  if (static_cast<std::size_t>(in.gcount()) != wanted) throw FileError("cannot read the file");
  return bytes;
}

bool is_gzip(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b;
}

Bytes gunzip(std::span<const std::uint8_t> compressed, std::size_t max_bytes) {
  Bytes out;
  z_stream stream{};
  // 16 + MAX_WBITS: a gzip wrapper only (its CRC and length are checked at each member's end).
  if (inflateInit2(&stream, 16 + MAX_WBITS) != Z_OK) throw FileError("zlib cannot start");
  struct End {
    z_stream* s;
    ~End() { inflateEnd(s); }
  } end{&stream};
  std::size_t in_at = 0;
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  constexpr std::size_t kMaxIn = std::numeric_limits<uInt>::max();
  bool stream_ended = false;
  while (out.size() < max_bytes) {
    if (stream.avail_in == 0) {
      const std::size_t n = std::min(compressed.size() - in_at, kMaxIn);
      stream.next_in = const_cast<Bytef*>(compressed.data() + in_at);
      stream.avail_in = static_cast<uInt>(n);
      in_at += n;
    }
    const std::size_t room = std::min(max_bytes - out.size(), kChunk);
    const std::size_t before = out.size();
    out.resize(before + room);
    stream.next_out = out.data() + before;
    stream.avail_out = static_cast<uInt>(room);
    const int status = inflate(&stream, Z_NO_FLUSH);
    out.resize(before + (room - stream.avail_out));
    if (status == Z_STREAM_END) {
      // Another member may follow; anything else after the end is ignored.
      const std::size_t rest = stream.avail_in + (compressed.size() - in_at);
      const std::size_t next = compressed.size() - rest;
      if (rest >= 2 && compressed[next] == 0x1f && compressed[next + 1] == 0x8b) {
        if (inflateReset(&stream) != Z_OK) throw FileError("zlib cannot restart");
        continue;
      }
      stream_ended = true;
      break;
    }
    if (status == Z_BUF_ERROR && stream.avail_in == 0 && in_at == compressed.size()) {
      throw FileError("the gzip stream is truncated");
    }
    if (status != Z_OK && status != Z_BUF_ERROR) {
      throw FileError(std::string("the gzip stream is damaged (") +
                      (stream.msg != nullptr ? stream.msg : "zlib error") + ")");
    }
    if (status == Z_BUF_ERROR && stream.avail_out != 0 && stream.avail_in == 0 &&
        in_at == compressed.size()) {
      throw FileError("the gzip stream is truncated");
    }
  }
  (void)stream_ended;
  return out;
}

Bytes read_maybe_gzip(const std::filesystem::path& path, std::size_t max_bytes) {
  Bytes head = read_file(path, 2);
  if (!is_gzip(head)) return read_file(path, max_bytes);
  const Bytes compressed = read_file(path);
  return gunzip(compressed, max_bytes);
}

}  // namespace typemerge::volume_file
