// Fuzz target: one file through the loader's parse-and-validate path, exactly as scan_folder
// and load_series use it: read_headers, then read_frames_hu on every frame it accepted.
//
// Properties (a violation aborts, so libFuzzer keeps the input):
//  * read_headers never throws (scan_folder calls it without a try: one bad file must never
//    stop the scan) and never returns frames together with a skip reason;
//  * an accepted frame has the attributes the geometry and the pixel reader rely on;
//  * read_frames_hu on accepted frames throws nothing but PixelError, and returns the range of
//    the values it wrote;
//  * decoded into int16 samples (as the loader does for integer rescale), the frames throw
//    only PixelError or NotInt16, and when they succeed hold exactly the float route's values
//    (the int16 decoders are separate code: integers, and SSE2 for slope 1);
//  * plus everything AddressSanitizer and UndefinedBehaviorSanitizer catch on the way.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "dicom/header_reader.h"
#include "dicom/pixel_reader.h"

namespace {

namespace fs = std::filesystem;

// One scratch file per process, in memory when /dev/shm exists.
const fs::path& scratch_file() {
  static const fs::path path = [] {
    std::error_code error;
    const fs::path folder = fs::is_directory("/dev/shm", error) ? fs::path("/dev/shm")
                                                                 : fs::temp_directory_path();
    return folder / ("typemerge_fuzz_dicom_" + std::to_string(::getpid()) + ".dcm");
  }();
  return path;
}

void remove_scratch_file() {
  std::error_code error;
  fs::remove(scratch_file(), error);
}

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_dicom_file: property violated: %s\n", property);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  typemerge::dicom::silence_dcmtk_log();
  std::atexit(remove_scratch_file);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace typemerge::dicom;
  {
    std::ofstream out(scratch_file(), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  HeaderReadOptions options;
  options.allow_non_ct_modality = size > 0 && (data[size - 1] & 1) != 0;
  // Small enough that libFuzzer's 2 GB RSS limit is never the finding; the check itself is
  // the same code as at the default 4 GB.
  options.max_pixel_bytes_per_file = std::uint64_t{16} << 20;

  HeaderReadResult read;
  try {
    read = read_headers(scratch_file(), options);
  } catch (...) {
    violated("read_headers threw");
  }
  if (!read.frames.empty() && !read.skip_reason.empty()) violated("frames and a skip reason");
  if (read.frames.empty() && read.skip_reason.empty()) violated("no frames and no skip reason");
  if (read.frames.empty()) return 0;

  std::vector<std::vector<float>> buffers;
  std::vector<FrameTarget> targets;
  buffers.reserve(read.frames.size());
  for (const SliceHeader& frame : read.frames) {
    if (frame.rows == 0 || frame.columns == 0 || !frame.position || !frame.orientation ||
        !frame.pixel_spacing || !((*frame.pixel_spacing)[0] > 0) ||
        !((*frame.pixel_spacing)[1] > 0) || frame.rescale_slope == 0) {
      violated("an accepted frame lacks what the loader relies on");
    }
    buffers.emplace_back(std::size_t{frame.rows} * frame.columns);
    targets.push_back({&frame, buffers.back().data()});
  }
  std::pair<float, float> range;
  try {
    range = read_frames_hu(targets);
  } catch (const PixelError&) {
    return 0;  // a refusal with a message: the expected outcome for a damaged file
  } catch (...) {
    violated("read_frames_hu threw something other than PixelError");
  }
  float lowest = INFINITY, highest = -INFINITY;
  for (const std::vector<float>& frame : buffers) {
    for (const float v : frame) {
      lowest = std::min(lowest, v);
      highest = std::max(highest, v);
    }
  }
  if (!(range.first == lowest && range.second == highest)) violated("the range is not the values'");

  // The same frames into int16 samples.
  std::vector<std::vector<std::int16_t>> samples;
  samples.reserve(read.frames.size());
  for (FrameTarget& target : targets) {
    samples.emplace_back(std::size_t{target.header->rows} * target.header->columns);
    target.hu = nullptr;
    target.hu16 = samples.back().data();
  }
  try {
    read_frames_hu(targets);
  } catch (const PixelError&) {
    violated("a file the float route read was refused into int16");
  } catch (const NotInt16&) {
    return 0;  // a value outside int16 or not an integer: the loader decodes floats instead
  } catch (...) {
    violated("read_frames_hu into int16 threw something other than PixelError or NotInt16");
  }
  for (std::size_t f = 0; f < samples.size(); ++f) {
    for (std::size_t p = 0; p < samples[f].size(); ++p) {
      if (static_cast<float>(samples[f][p]) != buffers[f][p]) {
        violated("an int16 sample differs from the float route's value");
      }
    }
  }
  return 0;
}
