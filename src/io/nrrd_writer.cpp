#include "io/nrrd_writer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "io/atomic_file.h"

namespace typemerge::io {
namespace {

std::string vector_text(const core::Vec3& v) {
  char text[128];
  std::snprintf(text, sizeof text, "(%.17g,%.17g,%.17g)", v[0], v[1], v[2]);
  return text;
}

}  // namespace

void write_nrrd(const core::Volume& volume, const std::filesystem::path& path,
                NrrdSampleType type) {
  const auto& size = volume.size();
  const auto& geometry = volume.geometry();
  std::string header = "NRRD0004\n# written by typemerge\n";
  header += type == NrrdSampleType::int16 ? "type: int16\n" : "type: float\n";
  header += "dimension: 3\nspace: left-posterior-superior\n";
  header += "sizes: " + std::to_string(size.nx) + " " + std::to_string(size.ny) + " " +
            std::to_string(size.nz) + "\n";
  header += "space directions: " + vector_text(geometry.axes[0]) + " " +
            vector_text(geometry.axes[1]) + " " + vector_text(geometry.axes[2]) + "\n";
  header += "kinds: domain domain domain\nendian: little\nencoding: raw\n";
  header += "space origin: " + vector_text(geometry.origin) + "\n\n";

  AtomicFile file(path);
  file.write(header);
  constexpr std::size_t kChunk = 1 << 18;
  if (volume.holds_int16()) {
    // Exact either way: the int16 samples as they are, or as the floats of their integers.
    const core::Int16Samples& samples = volume.int16_samples();
    if (type == NrrdSampleType::int16) {
      file.write(samples.data(), samples.size() * sizeof(std::int16_t));
    } else {
      std::vector<float> chunk;
      for (std::size_t start = 0; start < samples.size(); start += kChunk) {
        const std::size_t end = std::min(samples.size(), start + kChunk);
        chunk.assign(samples.begin() + static_cast<std::ptrdiff_t>(start),
                     samples.begin() + static_cast<std::ptrdiff_t>(end));
        file.write(chunk.data(), chunk.size() * sizeof(float));
      }
    }
    file.commit();
    return;
  }
  const core::Samples& samples = volume.samples();
  if (type == NrrdSampleType::float32) {
    file.write(samples.data(), samples.size() * sizeof(float));
  } else {
    std::vector<std::int16_t> chunk;
    for (std::size_t start = 0; start < samples.size(); start += kChunk) {
      const std::size_t end = std::min(samples.size(), start + kChunk);
      chunk.resize(end - start);
      for (std::size_t p = start; p < end; ++p) {
        const float clamped = std::clamp(std::nearbyint(samples[p]), -32768.0f, 32767.0f);
        chunk[p - start] = static_cast<std::int16_t>(clamped);
      }
      file.write(chunk.data(), chunk.size() * sizeof(std::int16_t));
    }
  }
  file.commit();
}

}  // namespace typemerge::io
