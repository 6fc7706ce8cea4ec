#include "volume_file/file_bytes.h"

#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <functional>
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

namespace {

// Inflates the gzip stream that `more` hands over in pieces (more(piece) sets the next piece,
// false at the end), handing the output to `sink` in pieces of at most 1 MiB: gunzip's loop.
template <typename More>
void inflate_pieces(More more, std::size_t max_bytes,
                    const std::function<void(std::span<const std::uint8_t>)>& sink) {
  z_stream stream{};
  // 16 + MAX_WBITS: a gzip wrapper only (its CRC and length are checked at each member's end).
  if (inflateInit2(&stream, 16 + MAX_WBITS) != Z_OK) throw FileError("zlib cannot start");
  struct End {
    z_stream* s;
    ~End() { inflateEnd(s); }
  } end{&stream};
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  constexpr std::size_t kMaxIn = std::numeric_limits<uInt>::max();
  Bytes chunk(std::min(kChunk, max_bytes));
  std::span<const std::uint8_t> piece;  // input not yet given to zlib
  Bytes joined;                         // a member's start cut between two pieces
  bool input_ended = false;
  auto refill = [&] {
    if (!piece.empty() || input_ended) return;
    input_ended = !more(piece);
  };
  std::size_t produced = 0;
  while (produced < max_bytes) {
    if (stream.avail_in == 0) {
      refill();
      const std::size_t n = std::min(piece.size(), kMaxIn);
      stream.next_in = const_cast<Bytef*>(piece.data());
      stream.avail_in = static_cast<uInt>(n);
      piece = piece.subspan(n);
    }
    const std::size_t room = std::min(max_bytes - produced, kChunk);
    stream.next_out = chunk.data();
    stream.avail_out = static_cast<uInt>(room);
    const int status = inflate(&stream, Z_NO_FLUSH);
    const std::size_t got = room - stream.avail_out;
    produced += got;
    if (got > 0) sink(std::span<const std::uint8_t>(chunk.data(), got));
    if (status == Z_STREAM_END) {
      // Another member may follow; anything else after the end is ignored.
      std::span<const std::uint8_t> rest(stream.next_in, stream.avail_in);
      if (rest.size() < 2) {
        // Peek at the next piece for a member's magic.
        Bytes tail(rest.begin(), rest.end());  // rest may point into `joined`
        tail.insert(tail.end(), piece.begin(), piece.end());
        piece = {};
        while (tail.size() < 2) {
          std::span<const std::uint8_t> next;
          if (input_ended || !more(next)) {
            input_ended = true;
            break;
          }
          tail.insert(tail.end(), next.begin(), next.end());
        }
        joined.swap(tail);
        rest = joined;
      }
      if (rest.size() >= 2 && rest[0] == 0x1f && rest[1] == 0x8b) {
        if (inflateReset(&stream) != Z_OK) throw FileError("zlib cannot restart");
        stream.next_in = const_cast<Bytef*>(rest.data());
        stream.avail_in = static_cast<uInt>(rest.size());
        continue;
      }
      break;
    }
    const bool no_more_input = stream.avail_in == 0 && piece.empty() && (refill(), piece.empty());
    if (status == Z_BUF_ERROR && no_more_input) {
      throw FileError("the gzip stream is truncated");
    }
    if (status != Z_OK && status != Z_BUF_ERROR) {
      throw FileError(std::string("the gzip stream is damaged (") +
                      (stream.msg != nullptr ? stream.msg : "zlib error") + ")");
    }
  }
}

}  // namespace

void gunzip_into(std::span<const std::uint8_t> compressed, std::size_t max_bytes,
                 const std::function<void(std::span<const std::uint8_t>)>& sink) {
  bool given = false;
  inflate_pieces(
      [&](std::span<const std::uint8_t>& piece) {
        if (given) return false;
        given = true;
        piece = compressed;
        return true;
      },
      max_bytes, sink);
}

void gunzip_file_into(const std::filesystem::path& path, std::size_t max_bytes,
                      const std::function<void(std::span<const std::uint8_t>)>& sink) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError("cannot open the file");
  Bytes buffer(std::size_t{1} << 20);
  inflate_pieces(
      [&](std::span<const std::uint8_t>& piece) {
        if (!in) return false;
        in.read(reinterpret_cast<char*>(buffer.data()), static_cast<std::streamsize>(buffer.size()));
        const auto got = static_cast<std::size_t>(in.gcount());
        if (got == 0) return false;
        piece = std::span<const std::uint8_t>(buffer.data(), got);
        return true;
      },
      max_bytes, sink);
}

Bytes gunzip(std::span<const std::uint8_t> compressed, std::size_t max_bytes) {
  Bytes out;
  gunzip_into(compressed, max_bytes,
              [&](std::span<const std::uint8_t> part) { out.insert(out.end(), part.begin(), part.end()); });
  return out;
}

Bytes read_maybe_gzip(const std::filesystem::path& path, std::size_t max_bytes) {
  Bytes head = read_file(path, 2);
  if (!is_gzip(head)) return read_file(path, max_bytes);
  Bytes out;
  gunzip_file_into(path, max_bytes, [&](std::span<const std::uint8_t> part) {
    out.insert(out.end(), part.begin(), part.end());
  });
  return out;
}

}  // namespace typemerge::volume_file
