#include "dicom/nesting_prescan.h"

#include <zlib.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <string_view>
#include <algorithm>
#include <vector>

namespace typemerge::dicom {
namespace {

constexpr std::uint32_t kUndefinedLength = 0xFFFFFFFFu;
constexpr std::size_t kMaxInflatedBytes = std::size_t{64} << 20;  // bounds a deflate bomb

// The walk reads from a byte buffer: the file's header part, or the inflated data set.
class ByteReader {
 public:
  explicit ByteReader(std::vector<unsigned char> bytes) : bytes_(std::move(bytes)) {}
  std::size_t pos() const { return pos_; }
  std::size_t size() const { return bytes_.size(); }
  bool has(std::size_t n) const { return pos_ <= bytes_.size() && bytes_.size() - pos_ >= n; }
  void skip(std::size_t n) { pos_ = has(n) ? pos_ + n : bytes_.size(); }
  void seek(std::size_t at) { pos_ = std::min(at, bytes_.size()); }
  std::uint16_t u16(bool big_endian) {
    const unsigned a = bytes_[pos_], b = bytes_[pos_ + 1];
    pos_ += 2;
    return static_cast<std::uint16_t>(big_endian ? (a << 8 | b) : (b << 8 | a));
  }
  std::uint32_t u32(bool big_endian) {
    const std::uint32_t lo = u16(big_endian), hi = u16(big_endian);
    return big_endian ? (lo << 16 | hi) : (hi << 16 | lo);
  }
  std::string_view chars(std::size_t at, std::size_t n) const {
    return {reinterpret_cast<const char*>(bytes_.data() + at), n};
  }
  const std::vector<unsigned char>& bytes() const { return bytes_; }

 private:
  std::vector<unsigned char> bytes_;
  std::size_t pos_ = 0;
};

bool looks_like_vr(std::string_view vr) {
  return vr.size() == 2 && vr[0] >= 'A' && vr[0] <= 'Z' && vr[1] >= 'A' && vr[1] <= 'Z';
}

// Whether an explicit-VR element has 2 reserved bytes and a 4-byte length, as DCMTK reads it
// (DcmVR::setVR): the long standard VRs and any other two capital letters (an unknown VR, read
// like UN); the short standard VRs, and two bytes that are not capital letters (its
// EVR_UNKNOWN2B), have a 2-byte length.
bool is_long_vr(std::string_view vr) {
  if (!looks_like_vr(vr)) return false;
  static constexpr std::array<std::string_view, 21> kShort = {
      "AE", "AS", "AT", "CS", "DA", "DS", "DT", "FL", "FD", "IS", "LO",
      "LT", "PN", "SH", "SL", "SS", "ST", "TM", "UI", "UL", "US"};
  for (auto v : kShort) {
    if (v == vr) return false;
  }
  return true;
}

struct Encoding {
  bool explicit_vr = true;
  bool big_endian = false;
};

// Walks elements from the reader's position to its end (or the pixel data). Containers with
// a defined length close when the position passes their end; undefined ones at delimiters.
// When the reader holds the whole data set (`whole`), a value longer than what is left of it
// is an error: DCMTK reads a deflated data set in one pass and allocates every declared
// length as it goes (a 755-byte file declaring 3.3 GB, found by fuzz_dicom_file).
int walk(ByteReader& in, Encoding enc, int max_depth, std::string& error,
         NestingReport* pixel_report, bool whole) {
  std::vector<std::size_t> open_ends;  // end offset of each open container (npos: undefined)
  int deepest = 0;
  auto close_finished = [&] {
    while (!open_ends.empty() && open_ends.back() != std::string::npos &&
           in.pos() >= open_ends.back()) {
      open_ends.pop_back();
    }
  };
  while (in.has(8)) {
    close_finished();
    const std::uint16_t group = in.u16(enc.big_endian);
    const std::uint16_t element = in.u16(enc.big_endian);
    if (group == 0xFFFE) {  // item, item delimiter, sequence delimiter: always 4-byte length
      const std::uint32_t length = in.u32(enc.big_endian);
      if (element == 0xE000) {
        open_ends.push_back(length == kUndefinedLength ? std::string::npos : in.pos() + length);
      } else if (!open_ends.empty()) {
        open_ends.pop_back();  // E00D closes the item, E0DD the sequence
      }
    } else {
      std::uint32_t length = 0;
      bool sequence = false;
      if (enc.explicit_vr) {
        const std::string_view vr = in.chars(in.pos(), 2);
        sequence = vr == "SQ";
        in.skip(2);
        if (is_long_vr(vr)) {
          in.skip(2);
          if (!in.has(4)) break;
          length = in.u32(enc.big_endian);
        } else {
          length = in.u16(enc.big_endian);
        }
      } else {
        length = in.u32(enc.big_endian);
      }
      // Pixel data in a file's head: note where it is and stop (it may run past the head). In
      // a whole data set (deflated) the walk goes on: DCMTK parses what follows too.
      if (group == 0x7FE0 && element == 0x0010 && open_ends.empty() && pixel_report != nullptr) {
        pixel_report->pixel_data_offset = in.pos();
        pixel_report->pixel_data_length = length;
        break;
      }
      // Undefined length means a sequence (or UN-encoded one); an implicit-VR element of
      // defined length is a sequence when its value starts with an item tag.
      if (!sequence && length != kUndefinedLength && in.has(4)) {
        const auto& b = in.bytes();
        const std::size_t p = in.pos();
        sequence = enc.big_endian ? (b[p] == 0xFF && b[p + 1] == 0xFE && b[p + 2] == 0xE0 &&
                                     b[p + 3] == 0x00)
                                  : (b[p] == 0xFE && b[p + 1] == 0xFF && b[p + 2] == 0x00 &&
                                     b[p + 3] == 0xE0);
      }
      if (length == kUndefinedLength || sequence) {
        open_ends.push_back(length == kUndefinedLength ? std::string::npos : in.pos() + length);
      } else if (whole && !in.has(length)) {
        char tag[16];
        std::snprintf(tag, sizeof tag, "(%04X,%04X)", unsigned{group}, unsigned{element});
        error = std::string("element ") + tag + " declares " + std::to_string(length) +
                " bytes, more than the " + std::to_string(in.size()) + "-byte data set holds";
        return deepest / 2;
      } else {
        in.skip(length);
      }
    }
    deepest = std::max(deepest, static_cast<int>(open_ends.size()));
    if (deepest > 2 * max_depth) {  // a sequence and its item are two levels
      error = "sequences nested more than " + std::to_string(max_depth) + " levels deep";
      return deepest / 2;
    }
  }
  return deepest / 2;
}

std::vector<unsigned char> read_head(const std::filesystem::path& file, std::string& error) {
  std::ifstream stream(file, std::ios::binary);
  if (!stream) {
    error = "cannot open";
    return {};
  }
  // Headers, even with large private blocks, sit well within the first 16 MiB; a nested bomb
  // that needs more bytes than that to exceed the depth limit is shallower than DCMTK's limit.
  constexpr std::size_t kHeadBytes = std::size_t{16} << 20;
  std::error_code size_error;
  const auto file_size = std::filesystem::file_size(file, size_error);
  std::vector<unsigned char> bytes(size_error ? kHeadBytes
                                              : std::min<std::size_t>(kHeadBytes, file_size));
  stream.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  bytes.resize(static_cast<std::size_t>(stream.gcount()));
  return bytes;
}

// Inflates a raw deflate stream, up to kMaxInflatedBytes; `complete` says whether the stream
// ended properly (Z_STREAM_END).
std::vector<unsigned char> inflate_raw(const unsigned char* data, std::size_t size,
                                       bool& complete) {
  std::vector<unsigned char> out;
  complete = false;
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) return out;
  z.next_in = const_cast<unsigned char*>(data);
  z.avail_in = static_cast<uInt>(size);
  std::array<unsigned char, 1 << 16> chunk{};
  int status = Z_OK;
  while (status == Z_OK && out.size() < kMaxInflatedBytes) {
    z.next_out = chunk.data();
    z.avail_out = static_cast<uInt>(chunk.size());
    status = inflate(&z, Z_NO_FLUSH);
    out.insert(out.end(), chunk.data(), chunk.data() + (chunk.size() - z.avail_out));
  }
  complete = status == Z_STREAM_END;
  inflateEnd(&z);
  return out;
}

}  // namespace

NestingReport prescan_nesting(const std::filesystem::path& file, int max_depth) {
  NestingReport report;
  std::vector<unsigned char> bytes = read_head(file, report.error);
  if (!report.error.empty()) return report;

  ByteReader head(std::move(bytes));
  Encoding dataset_encoding;
  const bool has_preamble = head.size() >= 132 && head.chars(128, 4) == "DICM";
  if (has_preamble) head.skip(132);
  // The meta header (group 0002) is always explicit little endian; read it to learn how the
  // data set is encoded.
  // Like DCMTK, the meta header ends where its group length (0002,0000) says when it has one
  // (whatever groups the elements inside claim), else at the first element of another group.
  // `meta_clean`: every element is of group 0002 with a real VR, and they end exactly where
  // the group length says — the only meta header after which a deflated data set is parsed
  // (where DCMTK would start inflating a damaged one is guesswork; it allocates as it reads).
  const std::size_t meta_start = head.pos();
  std::string transfer_syntax;
  std::optional<std::size_t> meta_end;
  bool meta_clean = true;
  bool transfer_syntax_seen = false;
  int previous_element = -1;  // elements ascend in a well-formed header (PS3.5 7.1)
  while (head.has(8) && (!meta_end || head.pos() < *meta_end)) {
    const std::size_t start = head.pos();
    const std::uint16_t group = head.u16(false);
    const std::uint16_t element = head.u16(false);
    if (!meta_end && group != 0x0002) {
      head.seek(start);
      break;
    }
    const std::string_view vr = head.chars(head.pos(), 2);
    meta_clean = meta_clean && group == 0x0002 && looks_like_vr(vr) && element > previous_element;
    previous_element = element;
    head.skip(2);
    std::uint32_t length = 0;
    if (is_long_vr(vr)) {
      head.skip(2);
      if (!head.has(4)) break;
      length = head.u32(false);
    } else {
      length = head.u16(false);
    }
    if (group == 0x0002 && element == 0x0000 && length == 4 && head.has(4) && !meta_end) {
      const std::uint32_t group_length = head.u32(false);
      if (head.has(group_length)) meta_end = head.pos() + group_length;  // else not trusted
      continue;
    }
    // DCMTK keeps the first of two equal tags and ignores the second (a fuzzed file named
    // deflate first and another syntax second; taking the last walked compressed bytes as
    // explicit VR and missed a 3.7 GB pixel value). Duplicates also make the header unclean.
    if (group == 0x0002 && element == 0x0010 && head.has(length) && !transfer_syntax_seen) {
      transfer_syntax_seen = true;
      transfer_syntax = std::string(head.chars(head.pos(), length));
      while (!transfer_syntax.empty() &&
             (transfer_syntax.back() == '\0' || transfer_syntax.back() == ' ')) {
        transfer_syntax.pop_back();
      }
    }
    head.skip(length);
  }
  meta_clean = meta_clean && meta_end && head.pos() == *meta_end;
  if (meta_end) head.seek(*meta_end);

  if (transfer_syntax == "1.2.840.10008.1.2") {
    dataset_encoding.explicit_vr = false;
  } else if (transfer_syntax == "1.2.840.10008.1.2.2") {
    dataset_encoding.big_endian = true;
  } else if (transfer_syntax.empty() && head.has(6)) {
    // No meta header: guess explicit VR from the first element's VR characters.
    dataset_encoding.explicit_vr = looks_like_vr(head.chars(head.pos() + 4, 2));
  }

  constexpr std::string_view kDeflated = "1.2.840.10008.1.2.1.99";
  const std::string_view meta_bytes =
      head.chars(meta_start, std::min<std::size_t>(head.size() - meta_start, 4096));
  if (transfer_syntax == kDeflated ||
      (!meta_clean && meta_bytes.find(kDeflated) != std::string_view::npos)) {
    report.deflated = true;
    if (!meta_clean) {
      report.error = "damaged file meta header in front of a deflated data set";
      return report;
    }
    const auto& all = head.bytes();
    bool complete = false;
    ByteReader inflated(inflate_raw(all.data() + head.pos(), all.size() - head.pos(), complete));
    const bool whole = inflated.size() < kMaxInflatedBytes;  // else cut at the bomb limit
    if (whole && !complete) {
      report.error = "damaged deflated data set (the compressed stream is cut or corrupt)";
      return report;
    }
    report.max_depth = walk(inflated, dataset_encoding, max_depth, report.error, nullptr, whole);
  } else {
    // The head may end before the file does; DCMTK loads long values lazily, and
    // check_value_lengths (header_reader) compares them with the file size.
    report.max_depth = walk(head, dataset_encoding, max_depth, report.error, &report, false);
  }
  return report;
}

}  // namespace typemerge::dicom
