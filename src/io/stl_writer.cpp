#include "io/stl_writer.h"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <locale>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include "io/atomic_file.h"

namespace typemerge::io {
namespace {

static_assert(std::endian::native == std::endian::little, "STL is little endian");

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kTriangleBytes = 50;

// Welds corners by exact coordinate bits: the writer emits shared vertices bit-identically.
struct CornerKey {
  std::array<std::uint32_t, 3> bits;
  bool operator==(const CornerKey&) const = default;
};
struct CornerHash {
  std::size_t operator()(const CornerKey& k) const {
    std::uint64_t h = 1469598103934665603ull;
    for (std::uint32_t b : k.bits) h = (h ^ b) * 1099511628211ull;
    return static_cast<std::size_t>(h);
  }
};

class Welder {
 public:
  explicit Welder(core::TriangleMesh& mesh) : mesh_(mesh) {}
  std::uint32_t add(const std::array<float, 3>& p) {
    CornerKey key{{std::bit_cast<std::uint32_t>(p[0] == 0 ? 0.0f : p[0]),
                   std::bit_cast<std::uint32_t>(p[1] == 0 ? 0.0f : p[1]),
                   std::bit_cast<std::uint32_t>(p[2] == 0 ? 0.0f : p[2])}};
    auto [it, inserted] = index_.try_emplace(key, static_cast<std::uint32_t>(mesh_.positions.size()));
    if (inserted) mesh_.positions.push_back(p);
    return it->second;
  }

 private:
  core::TriangleMesh& mesh_;
  std::unordered_map<CornerKey, std::uint32_t, CornerHash> index_;
};

}  // namespace

std::string stl_header(const std::string& version, const std::string& space) {
  std::string header = "typemerge " + version + " SPACE=" + space;
  header.resize(kHeaderBytes, ' ');
  return header;
}

void write_binary_stl(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                      const std::string& header) {
  if (header.size() != kHeaderBytes) throw std::invalid_argument("STL header must be 80 bytes");
  if (mesh.triangles.size() > 0xFFFFFFFFull) throw std::runtime_error("too many triangles for STL");
  AtomicFile file(path);
  file.write(header);
  const auto count = static_cast<std::uint32_t>(mesh.triangles.size());
  file.write(&count, sizeof count);
  // Records are assembled in a block buffer: one fwrite per 64 Ki triangles, not six per one.
  constexpr std::size_t kBlock = 1 << 16;
  std::vector<char> block(kBlock * kTriangleBytes);
  std::size_t used = 0;
  for (const auto& t : mesh.triangles) {
    const auto& a = mesh.positions[t[0]];
    const auto& b = mesh.positions[t[1]];
    const auto& c = mesh.positions[t[2]];
    const auto normal = core::facet_normal(mesh, t);
    const std::array<float, 3> n{float(normal[0]), float(normal[1]), float(normal[2])};
    char* record = block.data() + used * kTriangleBytes;
    std::memcpy(record, n.data(), 12);
    std::memcpy(record + 12, a.data(), 12);
    std::memcpy(record + 24, b.data(), 12);
    std::memcpy(record + 36, c.data(), 12);
    std::memset(record + 48, 0, 2);
    if (++used == kBlock) {
      file.write(block.data(), used * kTriangleBytes);
      used = 0;
    }
  }
  file.write(block.data(), used * kTriangleBytes);
  file.commit();
}

core::TriangleMesh read_stl(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path.string());
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  core::TriangleMesh mesh;
  Welder welder(mesh);
  std::uint32_t count = 0;
  if (bytes.size() >= kHeaderBytes + 4) std::memcpy(&count, bytes.data() + kHeaderBytes, 4);
  const bool binary = bytes.size() >= kHeaderBytes + 4 &&
                      bytes.size() == kHeaderBytes + 4 + std::size_t{count} * kTriangleBytes;
  if (binary) {
    mesh.triangles.reserve(count);
    for (std::uint32_t t = 0; t < count; ++t) {
      const char* record = bytes.data() + kHeaderBytes + 4 + std::size_t{t} * kTriangleBytes;
      std::array<std::uint32_t, 3> triangle{};
      for (int corner = 0; corner < 3; ++corner) {
        std::array<float, 3> p;
        std::memcpy(p.data(), record + 12 + 12 * corner, 12);
        triangle[corner] = welder.add(p);
      }
      mesh.triangles.push_back(triangle);
    }
    return mesh;
  }
  std::istringstream text(std::string(bytes.begin(), bytes.end()));
  text.imbue(std::locale::classic());  // "1.5" whatever the process locale says
  std::string word;
  if (!(text >> word) || word != "solid") {
    throw std::runtime_error(path.string() + " is neither a binary nor an ASCII STL file");
  }
  std::array<std::uint32_t, 3> triangle{};
  int corner = 0;
  while (text >> word) {
    if (word != "vertex") continue;
    std::array<float, 3> p;
    if (!(text >> p[0] >> p[1] >> p[2])) throw std::runtime_error("bad vertex in " + path.string());
    triangle[corner++] = welder.add(p);
    if (corner == 3) {
      mesh.triangles.push_back(triangle);
      corner = 0;
    }
  }
  return mesh;
}

}  // namespace typemerge::io
