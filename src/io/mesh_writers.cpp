#include "io/mesh_writers.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "io/atomic_file.h"
#include "io/three_mf_writer.h"
#include "io/stl_writer.h"

namespace typemerge::io {
namespace {

// Text output through snprintf with "%.9g": locale-independent for the C locale the process
// keeps, and round-trips a float exactly.
class TextBuffer {
 public:
  explicit TextBuffer(AtomicFile& file) : file_(file) { text_.reserve(1 << 20); }
  ~TextBuffer() = default;
  template <typename... Args>
  void print(const char* format, Args... args) {
    char line[256];
    const int n = std::snprintf(line, sizeof line, format, args...);
    text_.append(line, static_cast<std::size_t>(n));
    if (text_.size() > (1 << 20)) flush();
  }
  void flush() {
    file_.write(text_);
    text_.clear();
  }

 private:
  AtomicFile& file_;
  std::string text_;
};

void write_ascii_stl(const core::TriangleMesh& mesh, AtomicFile& file, const std::string& comment) {
  TextBuffer out(file);
  out.print("solid %s\n", comment.c_str());
  for (const auto& t : mesh.triangles) {
    const auto n = core::facet_normal(mesh, t);
    out.print(" facet normal %.9g %.9g %.9g\n  outer loop\n", n[0], n[1], n[2]);
    for (std::uint32_t v : t) {
      const auto& p = mesh.positions[v];
      out.print("   vertex %.9g %.9g %.9g\n", double(p[0]), double(p[1]), double(p[2]));
    }
    out.print("  endloop\n endfacet\n");
  }
  out.print("endsolid %s\n", comment.c_str());
  out.flush();
}

void write_ply(const core::TriangleMesh& mesh, AtomicFile& file, const std::string& comment) {
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment " + comment + "\n";
  header += "element vertex " + std::to_string(mesh.positions.size()) + "\n";
  header += "property float x\nproperty float y\nproperty float z\n";
  header += "element face " + std::to_string(mesh.triangles.size()) + "\n";
  header += "property list uchar uint vertex_indices\nend_header\n";
  file.write(header);
  file.write(mesh.positions.data(), mesh.positions.size() * sizeof(mesh.positions[0]));
  std::vector<char> block;
  block.reserve(13 * 65536);
  for (const auto& t : mesh.triangles) {
    block.push_back(3);
    const char* bytes = reinterpret_cast<const char*>(t.data());
    block.insert(block.end(), bytes, bytes + 12);
    if (block.size() >= 13 * 65536) {
      file.write(block.data(), block.size());
      block.clear();
    }
  }
  file.write(block.data(), block.size());
}

void write_obj(const core::TriangleMesh& mesh, AtomicFile& file, const std::string& comment) {
  TextBuffer out(file);
  out.print("# %s\n", comment.c_str());
  for (const auto& p : mesh.positions) {
    out.print("v %.9g %.9g %.9g\n", double(p[0]), double(p[1]), double(p[2]));
  }
  for (const auto& t : mesh.triangles) out.print("f %u %u %u\n", t[0] + 1, t[1] + 1, t[2] + 1);
  out.flush();
}

}  // namespace

MeshFormat mesh_format_for(const std::filesystem::path& path, bool ascii_stl) {
  const std::string extension = path.extension().string();
  if (extension == ".stl" || extension == ".STL") {
    return ascii_stl ? MeshFormat::ascii_stl : MeshFormat::binary_stl;
  }
  if (extension == ".ply" || extension == ".PLY") return MeshFormat::ply;
  if (extension == ".obj" || extension == ".OBJ") return MeshFormat::obj;
  if (extension == ".3mf" || extension == ".3MF") return MeshFormat::three_mf;
  throw std::invalid_argument("unknown mesh format '" + extension +
                              "' (use .stl, .3mf, .ply or .obj)");
}

void write_mesh(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                MeshFormat format, const std::string& comment) {
  if (format == MeshFormat::binary_stl) {
    std::string header = comment;
    header.resize(80, ' ');  // the 80-byte STL header holds the comment, cut or padded
    write_binary_stl(mesh, path, header);
    return;
  }
  if (format == MeshFormat::three_mf) {
    write_3mf(mesh, path, comment);
    return;
  }
  AtomicFile file(path);
  switch (format) {
    case MeshFormat::ascii_stl: write_ascii_stl(mesh, file, comment); break;
    case MeshFormat::ply: write_ply(mesh, file, comment); break;
    case MeshFormat::obj: write_obj(mesh, file, comment); break;
    case MeshFormat::binary_stl:
    case MeshFormat::three_mf: break;
  }
  file.commit();
}

}  // namespace typemerge::io
