#include "io/three_mf_writer.h"

#include <Model/COM/NMR_DLLInterfaces.h>

#include <cstdio>
#include <stdexcept>
#include <vector>

#include "io/atomic_file.h"
#include "io/lib3mf_object.h"

namespace typemerge::io {
namespace {


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

// Every byte the package is made of (names, colours, positions, triangles), hashed (FNV-1a):
// the seed of its UUIDs, so that they are unique per content yet the same on every run.
class ContentHash {
 public:
  void mix(const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) hash_ = (hash_ ^ p[i]) * 1099511628211ull;
  }
  void mix(const std::string& text) { mix(text.c_str(), text.size() + 1); }
  std::uint64_t value() const { return hash_; }

 private:
  std::uint64_t hash_ = 14695981039346656037ull;
};

std::uint64_t package_hash(const std::vector<ThreeMfPart>& parts, const std::string& application) {
  ContentHash hash;
  hash.mix(application);
  for (const ThreeMfPart& part : parts) {
    hash.mix(part.name);
    hash.mix(part.srgb.data(), part.srgb.size());
    const core::TriangleMesh& mesh = *part.mesh;
    const std::uint64_t counts[2] = {mesh.positions.size(), mesh.triangles.size()};
    hash.mix(counts, sizeof counts);
    hash.mix(mesh.positions.data(), mesh.positions.size() * sizeof(mesh.positions[0]));
    hash.mix(mesh.triangles.data(), mesh.triangles.size() * sizeof(mesh.triangles[0]));
  }
  return hash.value();
}

// A UUID from the package's hash and a salt naming its use: lib3mf would draw random ones, and
// outputs must be byte-identical across runs. Version nibble 8 (custom), RFC 4122 variant.
std::string content_uuid(std::uint64_t package, std::uint64_t salt) {
  auto derive = [package](std::uint64_t seed) {
    ContentHash hash;
    hash.mix(&package, sizeof package);
    hash.mix(&seed, sizeof seed);
    return hash.value();
  };
  const std::uint64_t high = derive(salt * 2);
  const std::uint64_t low = derive(salt * 2 + 1);
  char text[40];
  std::snprintf(text, sizeof text, "%08x-%04x-%04x-%04x-%012llx", unsigned(high >> 32),
                unsigned((high >> 16) & 0xFFFF), unsigned(0x8000 | (high & 0x0FFF)),
                unsigned(0x8000 | ((low >> 48) & 0x3FFF)),
                static_cast<unsigned long long>(low & 0xFFFFFFFFFFFFull));
  return text;
}

// Salts of the UUIDs: the build, then an object and its build item per part.
constexpr std::uint64_t kBuildSalt = 1;
std::uint64_t object_salt(std::size_t part) { return 2 + 2 * std::uint64_t(part); }
std::uint64_t item_salt(std::size_t part) { return 3 + 2 * std::uint64_t(part); }

void add_object(NMR::PLib3MFModel* model, const ThreeMfPart& part, DWORD material_group,
                DWORD material_index, std::uint64_t package, std::size_t index) {
  const core::TriangleMesh& mesh = *part.mesh;
  if (mesh.positions.size() > 0xFFFFFFFFu || mesh.triangles.size() > 0xFFFFFFFFu) {
    throw std::runtime_error("3MF: more than 2^32 vertices or triangles in " + part.name);
  }
  std::vector<NMR::MODELMESHVERTEX> vertices(mesh.positions.size());
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    for (int c = 0; c < 3; ++c) vertices[v].m_fPosition[c] = mesh.positions[v][c];
  }
  std::vector<NMR::MODELMESHTRIANGLE> triangles(mesh.triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) triangles[t].m_nIndices[c] = mesh.triangles[t][c];
  }
  Lib3mfObject object, item, colour;
  check(NMR::lib3mf_model_addmeshobject(model, object.out<NMR::PLib3MFModelMeshObject>()), model,
        "adding a mesh");
  auto* o = object.get<NMR::PLib3MFModelMeshObject>();
  check(NMR::lib3mf_object_setnameutf8(o, part.name.c_str()), o, "naming a mesh");
  check(NMR::lib3mf_meshobject_setgeometry(o, vertices.data(), DWORD(vertices.size()),
                                           triangles.data(), DWORD(triangles.size())),
        o, "setting the geometry");
  // The object's default property (pid/pindex on <object>): its colour for every triangle.
  check(NMR::lib3mf_object_createdefaultpropertyhandler(
            o, colour.out<NMR::PLib3MFDefaultPropertyHandler>()),
        o, "colouring a mesh");
  check(NMR::lib3mf_defaultpropertyhandler_setbasematerial(
            colour.get<NMR::PLib3MFDefaultPropertyHandler>(), material_group, material_index),
        o, "colouring a mesh");
  check(NMR::lib3mf_model_addbuilditem(model, o, nullptr, item.out<NMR::PLib3MFModelBuildItem>()),
        model, "adding a build item");
  check(NMR::lib3mf_object_setuuidutf8(o, content_uuid(package, object_salt(index)).c_str()), o,
        "setting a UUID");
  check(NMR::lib3mf_builditem_setuuidutf8(item.get<NMR::PLib3MFModelBuildItem>(),
                                          content_uuid(package, item_salt(index)).c_str()),
        model, "setting a UUID");
}

}  // namespace

void write_3mf(const std::vector<ThreeMfPart>& parts, const std::filesystem::path& path,
               const std::string& application) {
  for (const ThreeMfPart& part : parts) {
    if (part.mesh == nullptr) throw std::invalid_argument("3MF: a part without a mesh");
  }
  const std::uint64_t package = package_hash(parts, application);
  Lib3mfObject model, materials, writer;
  check(NMR::lib3mf_createmodel(model.out<NMR::PLib3MFModel>()), nullptr, "creating the model");
  auto* m = model.get<NMR::PLib3MFModel>();
  check(NMR::lib3mf_model_setunit(m, NMR::MODELUNIT_MILLIMETER), m, "setting the unit");
  check(NMR::lib3mf_model_addmetadatautf8(m, "Application", application.c_str()), m,
        "adding the metadata");
  // One base material per part, named like it: slicers that keep materials (Cura, Bambu/Orca)
  // show its display colour; the group comes first so that objects can refer to it.
  check(NMR::lib3mf_model_addbasematerialgroup(m, materials.out<NMR::PLib3MFModelBaseMaterial>()),
        m, "adding the materials");
  auto* group = materials.get<NMR::PLib3MFModelBaseMaterial>();
  DWORD group_id = 0;
  check(NMR::lib3mf_basematerial_getresourceid(group, &group_id), m, "adding the materials");
  std::vector<DWORD> material_index(parts.size());
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const auto& rgb = parts[p].srgb;
    check(NMR::lib3mf_basematerial_addmaterialutf8(group, parts[p].name.c_str(), rgb[0], rgb[1],
                                                   rgb[2], &material_index[p]),
          m, "adding a material");
    // addmaterial leaves alpha at 0 ("#RRGGBB00": fully transparent to a viewer): opaque.
    check(NMR::lib3mf_basematerial_setdisplaycolorrgba(group, material_index[p], rgb[0], rgb[1],
                                                       rgb[2], 0xFF),
          m, "colouring a material");
  }
  for (std::size_t p = 0; p < parts.size(); ++p) {
    add_object(m, parts[p], group_id, material_index[p], package, p);
  }
  check(NMR::lib3mf_model_setbuilduuidutf8(m, content_uuid(package, kBuildSalt).c_str()), m,
        "setting a UUID");
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

void write_3mf(const core::TriangleMesh& mesh, const std::filesystem::path& path,
               const std::string& application) {
  write_3mf({{&mesh, "surface", kSurfaceGrey}}, path, application);
}

}  // namespace typemerge::io
