// Decodes one JPEG 2000 frame (a J2K codestream or a JP2 file in memory) with OpenJPEG.
//
// Debian's DCMTK has no JPEG 2000 codec; OpenJPEG is the reference open decoder and is in
// Debian, so JPEG 2000 series load instead of being refused.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace typemerge::dicom {

struct DecodedJpeg2000 {
  std::uint32_t width = 0, height = 0;
  bool is_signed = false;
  std::uint32_t precision = 0;
  std::vector<std::int32_t> samples;  // stored pixel values, row by row
};

// Throws std::runtime_error with OpenJPEG's reason on a damaged or unsupported codestream.
DecodedJpeg2000 decode_jpeg2000(const std::uint8_t* data, std::size_t size);

}  // namespace typemerge::dicom
