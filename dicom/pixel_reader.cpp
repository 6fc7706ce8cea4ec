#include "dicom/pixel_reader.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>

#include "dicom/header_reader.h"
#include "dicom/jpeg2000_decoder.h"
#include "dicom/nesting_prescan.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace typemerge::dicom {
namespace {

void register_decoders_once() {
  static std::once_flag once;
  std::call_once(once, [] {
    silence_dcmtk_log();
    DJDecoderRegistration::registerCodecs();
    DJLSDecoderRegistration::registerCodecs();
    DcmRLEDecoderRegistration::registerCodecs();
  });
}

bool is_jpeg2000(E_TransferSyntax xfer) {
  return xfer == EXS_JPEG2000LosslessOnly || xfer == EXS_JPEG2000 ||
         xfer == EXS_JPEG2000MulticomponentLosslessOnly || xfer == EXS_JPEG2000Multicomponent;
}

// How to turn a stored word into a signed value: BitsStored bits ending at HighBit.
struct StoredLayout {
  unsigned shift = 0;
  std::uint32_t mask = 0;
  std::int32_t sign_bit = 0;  // 0 for unsigned data

  StoredLayout(unsigned bits_stored, unsigned high_bit, bool is_signed)
      : shift(high_bit + 1 - bits_stored),
        mask(bits_stored >= 32 ? 0xFFFFFFFFu : (1u << bits_stored) - 1),
        sign_bit(is_signed ? std::int32_t{1} << (bits_stored - 1) : 0) {}

  std::int32_t value(std::uint32_t word) const {
    const auto bits = static_cast<std::int32_t>((word >> shift) & mask);
    return (sign_bit != 0 && (bits & sign_bit)) ? bits - 2 * sign_bit : bits;
  }
};

struct HuMapping {
  double slope, intercept;
  bool has_padding;
  std::int32_t padding_low, padding_high;

  explicit HuMapping(const SliceHeader& h)
      : slope(h.rescale_slope), intercept(h.rescale_intercept),
        has_padding(h.pixel_padding_value.has_value()),
        padding_low(h.pixel_padding_value.value_or(0)),
        padding_high(h.pixel_padding_range_limit.value_or(h.pixel_padding_value.value_or(0))) {
    if (padding_low > padding_high) std::swap(padding_low, padding_high);
  }
  float hu(std::int32_t stored) const {
    if (has_padding && stored >= padding_low && stored <= padding_high) return kAirHu;
    return static_cast<float>(stored * slope + intercept);
  }
  // Whether hu() is stored · slope + intercept in integers: both are integers small enough
  // that every stored value (|stored| < 2³¹) maps exactly in 64-bit integers, as it does in
  // double, and the padding's air is an integer.
  bool integral() const {
    constexpr double kLimit = 1 << 20;
    return slope == std::trunc(slope) && intercept == std::trunc(intercept) &&
           std::fabs(slope) <= kLimit && std::fabs(intercept) <= kLimit &&
           kAirHu == std::trunc(kAirHu);
  }
};

// The lowest and highest value a frame was given.
struct ValueRange {
  float lowest = std::numeric_limits<float>::infinity();
  float highest = -std::numeric_limits<float>::infinity();
  void add(const ValueRange& other) {
    lowest = std::min(lowest, other.lowest);
    highest = std::max(highest, other.highest);
  }
};

// Writes value(p) for the frame's n pixels into the target's floats or int16 samples and
// returns their range. An int16 value is the float's own integer (integer rescale makes every
// value an integer), so both targets hold the same values; one out of range throws NotInt16.
template <typename Value>
ValueRange write_frame(const FrameTarget& target, std::size_t n, Value&& value) {
  ValueRange range;
  if (target.hu != nullptr) {
    for (std::size_t p = 0; p < n; ++p) {
      const float v = value(p);
      target.hu[p] = v;
      range.lowest = std::min(range.lowest, v);
      range.highest = std::max(range.highest, v);
    }
    return range;
  }
  bool fits = true;
  for (std::size_t p = 0; p < n; ++p) {
    const float v = value(p);
    fits = fits && v >= -32768.0f && v <= 32767.0f && v == std::trunc(v);
    target.hu16[p] = static_cast<std::int16_t>(fits ? v : 0.0f);
    range.lowest = std::min(range.lowest, v);
    range.highest = std::max(range.highest, v);
  }
  if (!fits) throw NotInt16(target.header->path.filename().string() + ": a value outside int16");
  return range;
}

// write_frame for stored values `stored(p)` under an integral mapping into int16 samples, in
// integers: the same values as the float route (each an integer there too), without its
// double arithmetic and per-sample tests (that route was about 10 % of a bone conversion of
// the abdomen on one thread, perf). Out of int16 throws NotInt16, as write_frame does.
template <typename Stored>
ValueRange write_frame_integral(const FrameTarget& target, std::size_t n, const HuMapping& mapping,
                                Stored&& stored) {
  const auto slope = static_cast<std::int64_t>(mapping.slope);
  const auto intercept = static_cast<std::int64_t>(mapping.intercept);
  const auto air = static_cast<std::int64_t>(kAirHu);
  std::int64_t lowest = std::numeric_limits<std::int64_t>::max();
  std::int64_t highest = std::numeric_limits<std::int64_t>::min();
  for (std::size_t p = 0; p < n; ++p) {
    const std::int32_t s = stored(p);
    const std::int64_t v =
        mapping.has_padding && s >= mapping.padding_low && s <= mapping.padding_high
            ? air
            : s * slope + intercept;
    lowest = std::min(lowest, v);
    highest = std::max(highest, v);
    target.hu16[p] = static_cast<std::int16_t>(v);
  }
  if (lowest < std::numeric_limits<std::int16_t>::min() ||
      highest > std::numeric_limits<std::int16_t>::max()) {
    throw NotInt16(target.header->path.filename().string() + ": a value outside int16");
  }
  ValueRange range;
  if (n > 0) range = {static_cast<float>(lowest), static_cast<float>(highest)};
  return range;
}

// write_frame_integral for 16-bit words under slope 1 (nearly every CT series), eight samples
// at a time with SSE2: the same values, and the same NotInt16 for one out of range. The
// compilers leave the scalar loop scalar (64-bit products, the padding's branch), and it was
// about 6 % of a bone conversion's CPU on a 300-slice series (perf); other slopes and 8-bit
// words take the scalar loop.
ValueRange write_words_integral(const FrameTarget& target, std::size_t n,
                                const HuMapping& mapping, const StoredLayout& layout,
                                const Uint16* words) {
  std::size_t p = 0;
  std::int32_t lowest = std::numeric_limits<std::int32_t>::max();
  std::int32_t highest = std::numeric_limits<std::int32_t>::min();
#if defined(__SSE2__)
  if (mapping.slope == 1.0) {
    const __m128i zero = _mm_setzero_si128();
    const __m128i shift = _mm_cvtsi32_si128(static_cast<int>(layout.shift));
    const __m128i mask = _mm_set1_epi16(static_cast<std::int16_t>(layout.mask & 0xFFFFu));
    const __m128i sign = _mm_set1_epi32(layout.sign_bit);
    const __m128i intercept = _mm_set1_epi32(static_cast<std::int32_t>(mapping.intercept));
    const __m128i air = _mm_set1_epi32(static_cast<std::int32_t>(kAirHu));
    const __m128i pad_low = _mm_set1_epi32(mapping.padding_low);
    const __m128i pad_high = _mm_set1_epi32(mapping.padding_high);
    __m128i low = _mm_set1_epi32(lowest);
    __m128i high = _mm_set1_epi32(highest);
    // StoredLayout::value in four 32-bit lanes: (bits ^ sign) − sign sign-extends from the
    // stored width (sign 0: unsigned), then HuMapping's padding and intercept.
    auto hu = [&](__m128i bits) {
      const __m128i stored = _mm_sub_epi32(_mm_xor_si128(bits, sign), sign);
      const __m128i value = _mm_add_epi32(stored, intercept);
      if (!mapping.has_padding) return value;
      const __m128i outside =
          _mm_or_si128(_mm_cmpgt_epi32(pad_low, stored), _mm_cmpgt_epi32(stored, pad_high));
      return _mm_or_si128(_mm_and_si128(outside, value), _mm_andnot_si128(outside, air));
    };
    auto track = [&](__m128i v) {
      const __m128i below = _mm_cmplt_epi32(v, low);
      low = _mm_or_si128(_mm_and_si128(below, v), _mm_andnot_si128(below, low));
      const __m128i above = _mm_cmpgt_epi32(v, high);
      high = _mm_or_si128(_mm_and_si128(above, v), _mm_andnot_si128(above, high));
    };
    for (; p + 8 <= n; p += 8) {
      const __m128i loaded = _mm_loadu_si128(reinterpret_cast<const __m128i*>(words + p));
      const __m128i bits = _mm_and_si128(_mm_srl_epi16(loaded, shift), mask);
      const __m128i first = hu(_mm_unpacklo_epi16(bits, zero));
      const __m128i second = hu(_mm_unpackhi_epi16(bits, zero));
      track(first);
      track(second);
      // Saturated where out of int16, which the range check below refuses.
      _mm_storeu_si128(reinterpret_cast<__m128i*>(target.hu16 + p), _mm_packs_epi32(first, second));
    }
    alignas(16) std::array<std::int32_t, 4> lanes{};
    _mm_store_si128(reinterpret_cast<__m128i*>(lanes.data()), low);
    for (std::int32_t v : lanes) lowest = std::min(lowest, v);
    _mm_store_si128(reinterpret_cast<__m128i*>(lanes.data()), high);
    for (std::int32_t v : lanes) highest = std::max(highest, v);
  }
#endif
  FrameTarget rest = target;
  rest.hu16 = target.hu16 + p;
  ValueRange range = write_frame_integral(
      rest, n - p, mapping, [&](std::size_t q) { return layout.value(words[p + q]); });
  if (lowest < std::numeric_limits<std::int16_t>::min() ||
      highest > std::numeric_limits<std::int16_t>::max()) {
    throw NotInt16(target.header->path.filename().string() + ": a value outside int16");
  }
  if (p > 0) range.add({static_cast<float>(lowest), static_cast<float>(highest)});
  return range;
}

[[noreturn]] void fail(const SliceHeader& header, const std::string& reason) {
  throw PixelError(header.path.filename().string() + ": " + reason);
}

// DCMTK's JPEG decoder (dcmjpeg, DJCodecDecoder::scanJpegDataForBitDepth) walks the markers
// of a fragment to find its bit depth and never advances past a TEM marker (0xFF01): a
// fragment with one before its SOF hangs the process (fuzz_dicom_file, timeout-c20d8cfd…).
// This walks the markers the same way and says whether DCMTK's walk would end.
bool jpeg_bit_depth_scan_ends(const Uint8* data, std::uint32_t length) {
  std::uint32_t offset = 0;
  while (offset + 4 < length) {
    const unsigned marker = (unsigned{data[offset]} << 8) | data[offset + 1];
    const unsigned segment = (unsigned{data[offset + 2]} << 8) | data[offset + 3];
    if (marker == 0xFF01) return false;                                   // TEM: DCMTK loops
    if (marker >= 0xFFC0 && marker <= 0xFFCF && marker != 0xFFC4 && marker != 0xFFC8 &&
        marker != 0xFFCC) {
      return true;                                                         // SOF: depth found
    }
    if ((marker >= 0xFFD0 && marker <= 0xFFD9)) {
      offset += 2;                                                         // RSTn, SOI, EOI
    } else if (marker >= 0xFFC4 && marker <= 0xFFFE) {
      offset += segment + 2;                                               // marker segments
    } else if (marker == 0xFFFF) {
      offset += 1;                                                         // fill byte
    } else if (data[offset] == 0xFF && data[offset + 1] > 2 && data[offset + 1] <= 0xBF) {
      offset += 2;                                                         // reserved markers
    } else {
      return true;                                                         // DCMTK stops: error
    }
  }
  return true;
}

// Refuses JPEG (dcmjpeg) pixel data whose fragments DCMTK's bit-depth scan would not finish.
void check_jpeg_fragments(DcmDataset& dataset, E_TransferSyntax xfer, const SliceHeader& header) {
  const DcmXfer syntax(xfer);
  if (!syntax.isEncapsulated() || is_jpeg2000(xfer) || xfer == EXS_RLELossless ||
      xfer == EXS_JPEGLSLossless || xfer == EXS_JPEGLSLossy) {
    return;
  }
  DcmElement* element = nullptr;
  if (dataset.findAndGetElement(DCM_PixelData, element).bad() || element == nullptr) return;
  DcmPixelSequence* sequence = nullptr;
  if (static_cast<DcmPixelData*>(element)->getEncapsulatedRepresentation(xfer, nullptr, sequence)
          .bad() ||
      sequence == nullptr) {
    return;
  }
  for (unsigned long i = 1; i < sequence->card(); ++i) {
    DcmPixelItem* item = nullptr;
    Uint8* bytes = nullptr;
    if (sequence->getItem(item, i).bad() || item == nullptr ||
        item->getUint8Array(bytes).bad() || bytes == nullptr) {
      continue;
    }
    if (!jpeg_bit_depth_scan_ends(bytes, item->getLength())) {
      fail(header, "damaged JPEG data: a TEM marker before the frame header, which the JPEG "
                   "decoder cannot read past");
    }
  }
}

ValueRange read_jpeg2000(DcmDataset& dataset, E_TransferSyntax xfer,
                         const std::vector<FrameTarget>& targets) {
  const SliceHeader& header = *targets.front().header;
  DcmElement* element = nullptr;
  if (dataset.findAndGetElement(DCM_PixelData, element).bad() || element == nullptr) {
    fail(header, "no pixel data");
  }
  auto* pixel_data = static_cast<DcmPixelData*>(element);
  DcmPixelSequence* sequence = nullptr;
  if (pixel_data->getEncapsulatedRepresentation(xfer, nullptr, sequence).bad() || !sequence) {
    fail(header, "JPEG 2000 pixel data is not encapsulated");
  }
  const unsigned long fragments = sequence->card();  // item 0 is the basic offset table
  const std::uint32_t frames = header.frames_in_file;
  if (fragments < 2 || (frames > 1 && fragments - 1 != frames)) {
    fail(header, "JPEG 2000 data with " + std::to_string(fragments - 1) + " fragments for " +
                     std::to_string(frames) + " frames is not supported");
  }
  ValueRange range;
  for (const FrameTarget& target : targets) {
    std::vector<std::uint8_t> codestream;
    const unsigned long first = frames == 1 ? 1 : target.header->frame + 1;
    const unsigned long last = frames == 1 ? fragments - 1 : first;
    for (unsigned long f = first; f <= last; ++f) {
      DcmPixelItem* item = nullptr;
      Uint8* bytes = nullptr;
      if (sequence->getItem(item, f).bad() || item->getUint8Array(bytes).bad()) {
        fail(header, "unreadable JPEG 2000 fragment");
      }
      codestream.insert(codestream.end(), bytes, bytes + item->getLength());
    }
    DecodedJpeg2000 decoded;
    try {
      decoded = decode_jpeg2000(codestream.data(), codestream.size());
    } catch (const std::exception& error) {
      fail(header, error.what());
    }
    if (decoded.width != header.columns || decoded.height != header.rows) {
      fail(header, "JPEG 2000 frame is " + std::to_string(decoded.width) + "x" +
                       std::to_string(decoded.height) + ", header says " +
                       std::to_string(header.columns) + "x" + std::to_string(header.rows));
    }
    const HuMapping mapping(*target.header);
    range.add(write_frame(target, decoded.samples.size(),
                          [&](std::size_t p) { return mapping.hu(decoded.samples[p]); }));
  }
  return range;
}

ValueRange read_native(DcmDataset& dataset, const std::vector<FrameTarget>& targets) {
  const SliceHeader& header = *targets.front().header;
  // Decoders may rewrite the pixel module (e.g. BitsStored of lossy JPEG): read it afresh.
  Uint16 bits_allocated = header.bits_allocated, bits_stored = header.bits_stored;
  Uint16 high_bit = header.high_bit, representation = header.pixel_representation;
  dataset.findAndGetUint16(DCM_BitsAllocated, bits_allocated);
  dataset.findAndGetUint16(DCM_BitsStored, bits_stored);
  dataset.findAndGetUint16(DCM_HighBit, high_bit);
  dataset.findAndGetUint16(DCM_PixelRepresentation, representation);
  if ((bits_allocated != 8 && bits_allocated != 16) || bits_stored == 0 ||
      bits_stored > bits_allocated || high_bit >= bits_allocated || high_bit + 1 < bits_stored) {
    fail(header, "inconsistent pixel module after decoding");
  }
  const StoredLayout layout(bits_stored, high_bit, representation == 1);
  const std::size_t frame_pixels = std::size_t{header.rows} * header.columns;
  const std::size_t total_pixels = frame_pixels * header.frames_in_file;

  DcmElement* element = nullptr;
  if (dataset.findAndGetElement(DCM_PixelData, element).bad() || element == nullptr) {
    fail(header, "no pixel data");
  }
  if (element->getLength() < total_pixels * (bits_allocated / 8u)) {
    fail(header, "pixel data is " + std::to_string(element->getLength()) + " bytes, expected " +
                     std::to_string(total_pixels * (bits_allocated / 8u)));
  }
  ValueRange range;
  if (bits_allocated == 16) {
    Uint16* words = nullptr;
    if (element->getUint16Array(words).bad() || words == nullptr) fail(header, "unreadable pixels");
    for (const FrameTarget& target : targets) {
      const HuMapping mapping(*target.header);
      const Uint16* frame = words + frame_pixels * target.header->frame;
      if (target.hu16 != nullptr && mapping.integral()) {
        range.add(write_words_integral(target, frame_pixels, mapping, layout, frame));
        continue;
      }
      range.add(write_frame(target, frame_pixels,
                            [&](std::size_t p) { return mapping.hu(layout.value(frame[p])); }));
    }
  } else {
    Uint8* bytes = nullptr;
    if (element->getUint8Array(bytes).bad() || bytes == nullptr) fail(header, "unreadable pixels");
    for (const FrameTarget& target : targets) {
      const HuMapping mapping(*target.header);
      const Uint8* frame = bytes + frame_pixels * target.header->frame;
      if (target.hu16 != nullptr && mapping.integral()) {
        range.add(write_frame_integral(target, frame_pixels, mapping,
                                       [&](std::size_t p) { return layout.value(frame[p]); }));
        continue;
      }
      range.add(write_frame(target, frame_pixels,
                            [&](std::size_t p) { return mapping.hu(layout.value(frame[p])); }));
    }
  }
  return range;
}

}  // namespace

std::string transfer_syntax_name(const std::string& uid) {
  const DcmXfer xfer(uid.c_str());
  if (xfer.getXfer() == EXS_Unknown) return "unknown transfer syntax " + uid;
  return xfer.getXferName();
}

std::pair<float, float> read_frames_hu(const std::vector<FrameTarget>& targets) {
  if (targets.empty()) return {0.0f, 0.0f};
  register_decoders_once();
  const SliceHeader& header = *targets.front().header;
  // The file may have changed since the scan; the nesting check is cheap, so repeat it.
  const NestingReport nesting = prescan_nesting(header.path);
  if (!nesting.error.empty()) fail(header, nesting.error);

  DcmFileFormat format;
  const OFCondition loaded = format.loadFile(OFFilename(header.path.c_str()));
  if (loaded.bad()) fail(header, std::string("cannot read: ") + loaded.text());
  DcmDataset& dataset = *format.getDataset();
  const E_TransferSyntax xfer = dataset.getOriginalXfer();
  try {
    if (is_jpeg2000(xfer)) {
      const ValueRange range = read_jpeg2000(dataset, xfer, targets);
      return {range.lowest, range.highest};
    }
    check_jpeg_fragments(dataset, xfer, header);
    const OFCondition decoded = dataset.chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
    if (decoded.bad() || !dataset.canWriteXfer(EXS_LittleEndianExplicit)) {
      fail(header, "unsupported transfer syntax " + transfer_syntax_name(header.transfer_syntax_uid) +
                       " (" + decoded.text() + ")");
    }
    const ValueRange range = read_native(dataset, targets);
    return {range.lowest, range.highest};
  } catch (const std::bad_alloc&) {
    fail(header, "out of memory while decoding");
  }
}

}  // namespace typemerge::dicom
