// Fuzz target: bytes as a NIfTI file (.nii, or .nii.gz when they start with the gzip magic)
// through the reader's whole path: inflate (bounded), parse_header, decode_nifti.
//
// Properties (a violation aborts, so libFuzzer keeps the input):
//  * the reader throws nothing but ReadError (and the inflater nothing but FileError);
//  * an accepted volume has as many samples as its size says, every one finite, and a
//    finite, non-singular geometry;
//  * plus everything AddressSanitizer and UndefinedBehaviorSanitizer catch on the way.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "nifti/nifti_reader.h"
#include "volume_file/file_bytes.h"

namespace {

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_nifti: property violated: %s\n", property);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace typemerge;
  std::span<const std::uint8_t> bytes(data, size);
  volume_file::Bytes inflated;
  nifti::ReadOptions options;
  options.max_volume_bytes = std::uint64_t{64} << 20;  // below libFuzzer's RSS limit
  try {
    if (volume_file::is_gzip(bytes)) {
      inflated = volume_file::gunzip(bytes, std::size_t{16} << 20);
      bytes = inflated;
    }
    const nifti::NiftiImage image = nifti::decode_nifti(bytes, options);
    const auto& grid = image.volume.size();
    if (grid.nx < 1 || grid.ny < 1 || grid.nz < 1 ||
        image.volume.sample_bytes() != static_cast<std::size_t>(grid.voxels()) *
                                            (image.volume.holds_int16() ? 2 : 4)) {
      violated("samples do not match the size");
    }
    image.volume.visit([&](const auto* samples) {  // float or int16 storage
      for (std::int64_t v = 0; v < grid.voxels(); ++v) {
        if (!std::isfinite(static_cast<float>(samples[v]))) violated("a non-finite sample");
      }
    });
    const double det = image.volume.geometry().determinant();
    if (!std::isfinite(det) || det == 0) violated("a singular or non-finite geometry");
  } catch (const nifti::ReadError&) {
  } catch (const volume_file::FileError&) {
  } catch (...) {
    violated("an exception other than ReadError or FileError");
  }
  return 0;
}
