// Decodes the pixels of one file into Hounsfield units, frame by frame.
//
// Uncompressed and every syntax DCMTK decodes (JPEG baseline/extended/lossless, JPEG-LS, RLE;
// only those decoders are registered) go through DCMTK; JPEG 2000 goes through OpenJPEG.
// Stored values honour BitsStored, HighBit and PixelRepresentation exactly; each frame's own
// RescaleSlope/RescaleIntercept is applied; PixelPaddingValue (and its range) become air.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "dicom/slice_header.h"

namespace typemerge::dicom {

inline constexpr float kAirHu = -1000.0f;

class PixelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Where one frame's HU go: `hu` (floats) or, when `hu` is null, `hu16` (int16, for a frame
// whose RescaleSlope and RescaleIntercept are integers).
struct FrameTarget {
  const SliceHeader* header;  // the frame to decode (all targets come from the same file)
  float* hu;                  // rows × columns floats, x fastest
  std::int16_t* hu16 = nullptr;  // rows × columns int16, x fastest (when hu is null)
};

// An int16 target met a value outside −32768…32767 (or not an integer): the caller decodes
// again into floats.
class NotInt16 : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Decodes every target's frame and returns the lowest and highest value written (0, 0 for no
// targets). Throws PixelError naming the file and the reason, or NotInt16.
std::pair<float, float> read_frames_hu(const std::vector<FrameTarget>& targets);

// Name of a transfer syntax for messages ("JPEG 2000 Image Compression (Lossless Only)").
std::string transfer_syntax_name(const std::string& uid);

}  // namespace typemerge::dicom
