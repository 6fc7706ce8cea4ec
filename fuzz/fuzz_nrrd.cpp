// Fuzz target: bytes as an attached NRRD file (header, blank line, raw or gzip data) through
// decode_nrrd and to_label_volume, as `convert` reads a .nrrd or .seg.nrrd.
//
// Properties (a violation aborts, so libFuzzer keeps the input):
//  * the reader throws nothing but ReadError;
//  * an accepted image has header.layers layers, each of the header's size with every sample
//    finite; its segments name existing layers, with labels > 0, (layer, label) unique;
//  * plus everything AddressSanitizer and UndefinedBehaviorSanitizer catch on the way.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <span>
#include <utility>

#include "nrrd/nrrd_reader.h"

namespace {

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_nrrd: property violated: %s\n", property);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace typemerge;
  nrrd::ReadOptions options;
  options.max_volume_bytes = std::uint64_t{64} << 20;  // below libFuzzer's RSS limit
  try {
    nrrd::NrrdImage image = nrrd::decode_nrrd(std::span<const std::uint8_t>(data, size), options);
    if (image.layers.size() != image.header.layers) violated("layer count");
    for (const core::Volume& layer : image.layers) {
      if (layer.size() != image.header.size ||
          layer.sample_bytes() != static_cast<std::size_t>(layer.size().voxels()) *
                                      (layer.holds_int16() ? 2 : 4)) {
        violated("a layer's size");
      }
      layer.visit([&](const auto* samples) {  // float or int16 storage
        for (std::int64_t v = 0; v < layer.size().voxels(); ++v) {
          if (!std::isfinite(static_cast<float>(samples[v]))) violated("a non-finite sample");
        }
      });
    }
    const core::LabelVolume labels = nrrd::to_label_volume(std::move(image));
    std::set<std::pair<std::size_t, std::int32_t>> seen;
    for (const core::Segment& s : labels.segments) {
      if (s.layer >= labels.layers.size() || s.label <= 0) violated("a segment's layer or label");
      if (!seen.insert({s.layer, s.label}).second) violated("two segments with one (layer, label)");
    }
  } catch (const nrrd::ReadError&) {
  } catch (...) {
    violated("an exception other than ReadError");
  }
  return 0;
}
