#include "io/three_mf_writer.h"

#include <Model/COM/NMR_DLLInterfaces.h>

#include <cstdio>
#include <stdexcept>
#include <vector>

#include "io/atomic_file.h"

namespace typemerge::io {
namespace {

// lib3mf 1.8's C interface hands out reference-counted objects; each is released here.
class Released {
 public:
  Released() = default;
  Released(const Released&) = delete;
  Released& operator=(const Released&) = delete;
  ~Released() {
    if (object_ != nullptr) NMR::lib3mf_release(object_);
  }
  template <typename T>
  T** out() {
    return reinterpret_cast<T**>(&object_);
  }
  template <typename T>
  T* get() const {
    return static_cast<T*>(object_);
  }

 private:
  NMR::PLib3MFBase* object_ = nullptr;
};

void check(HRESULT result, NMR::PLib3MFBase* context, const char* what) {
  if (result == LIB3MF_OK) return;
  std::string message = std::string("3MF: ") + what + " failed";
  DWORD code = 0;
  LPCSTR text = nullptr;
  if (context != nullptr && NMR::lib3mf_getlasterror(context, &code, &text) == LIB3MF_OK &&
      text != nullptr) {
    message += std::string(": ") + text;
  }
  throw std::runtime_error(message);
}

// A UUID from the mesh's bytes and a salt (FNV-1a, two 64-bit halves): lib3mf would draw
// random ones, and outputs must be byte-identical across runs. Version nibble 8 (custom).
std::string content_uuid(const core::TriangleMesh& mesh, std::uint64_t salt) {
  auto fnv = [&](std::uint64_t hash) {
    auto mix = [&hash](const void* data, std::size_t bytes) {
      const auto* p = static_cast<const unsigned char*>(data);
      for (std::size_t i = 0; i < bytes; ++i) hash = (hash ^ p[i]) * 1099511628211ull;
    };
    mix(mesh.positions.data(), mesh.positions.size() * sizeof(mesh.positions[0]));
    mix(mesh.triangles.data(), mesh.triangles.size() * sizeof(mesh.triangles[0]));
    return hash;
  };
  const std::uint64_t high = fnv(14695981039346656037ull ^ salt);
  const std::uint64_t low = fnv(14695981039346656037ull ^ (salt * 0x9E3779B97F4A7C15ull + 1));
  char text[40];
  std::snprintf(text, sizeof text, "%08x-%04x-%04x-%04x-%012llx", unsigned(high >> 32),
                unsigned((high >> 16) & 0xFFFF), unsigned(0x8000 | (high & 0x0FFF)),
                unsigned(0x8000 | ((low >> 48) & 0x3FFF)),
                static_cast<unsigned long long>(low & 0xFFFFFFFFFFFFull));
  return text;
}

}  // namespace

void write_3mf(const core::TriangleMesh& mesh, const std::filesystem::path& path,
               const std::string& name) {
  std::vector<NMR::MODELMESHVERTEX> vertices(mesh.positions.size());
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    for (int c = 0; c < 3; ++c) vertices[v].m_fPosition[c] = mesh.positions[v][c];
  }
  std::vector<NMR::MODELMESHTRIANGLE> triangles(mesh.triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) triangles[t].m_nIndices[c] = mesh.triangles[t][c];
  }
  if (vertices.size() > 0xFFFFFFFFu || triangles.size() > 0xFFFFFFFFu) {
    throw std::runtime_error("3MF: more than 2^32 vertices or triangles");
  }

  Released model, object, item, writer;
  check(NMR::lib3mf_createmodel(model.out<NMR::PLib3MFModel>()), nullptr, "creating the model");
  auto* m = model.get<NMR::PLib3MFModel>();
  check(NMR::lib3mf_model_setunit(m, NMR::MODELUNIT_MILLIMETER), m, "setting the unit");
  check(NMR::lib3mf_model_addmeshobject(m, object.out<NMR::PLib3MFModelMeshObject>()), m,
        "adding the mesh");
  auto* o = object.get<NMR::PLib3MFModelMeshObject>();
  check(NMR::lib3mf_object_setnameutf8(o, name.c_str()), o, "naming the mesh");
  check(NMR::lib3mf_meshobject_setgeometry(o, vertices.data(), DWORD(vertices.size()),
                                           triangles.data(), DWORD(triangles.size())),
        o, "setting the geometry");
  check(NMR::lib3mf_model_addbuilditem(m, o, nullptr, item.out<NMR::PLib3MFModelBuildItem>()), m,
        "adding the build item");
  check(NMR::lib3mf_object_setuuidutf8(o, content_uuid(mesh, 1).c_str()), o, "setting a UUID");
  check(NMR::lib3mf_builditem_setuuidutf8(item.get<NMR::PLib3MFModelBuildItem>(),
                                          content_uuid(mesh, 2).c_str()),
        m, "setting a UUID");
  check(NMR::lib3mf_model_setbuilduuidutf8(m, content_uuid(mesh, 3).c_str()), m, "setting a UUID");
  check(NMR::lib3mf_model_querywriter(m, "3mf", writer.out<NMR::PLib3MFModelWriter>()), m,
        "creating the writer");
  auto* w = writer.get<NMR::PLib3MFModelWriter>();
  // Into memory, then through AtomicFile: lib3mf writing to the final path directly would leave
  // a partial package behind an interrupted run.
  ULONG64 bytes = 0;
  check(NMR::lib3mf_writer_getstreamsize(w, &bytes), w, "sizing the package");
  std::vector<BYTE> buffer(static_cast<std::size_t>(bytes));
  check(NMR::lib3mf_writer_writetobuffer(w, buffer.data(), bytes), w, "writing the package");
  AtomicFile file(path);
  file.write(buffer.data(), buffer.size());
  file.commit();
}

}  // namespace typemerge::io
