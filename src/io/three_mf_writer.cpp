#include "io/three_mf_writer.h"

#include <Model/COM/NMR_DLLInterfaces.h>

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
