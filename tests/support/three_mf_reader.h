// Reads a 3MF package back with lib3mf (the library slicers' readers follow): the unit, the
// "Application" metadata and every mesh object with its name, its colour (the display colour of
// the base material its default property names) and its vertices and triangles, in file order.
// For tests only: it throws std::runtime_error on anything unexpected.
//
// lib3mf 1.8's reader leaks inside libzip; the test executables using this header run with a
// LeakSanitizer suppression for libzip only (tests/support/lib3mf_reader.supp).
#pragma once

#include <Model/COM/NMR_DLLInterfaces.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "io/lib3mf_object.h"

namespace typemerge::test {

struct ReadThreeMfObject {
  std::string name;
  std::string material_name;  // of its base material
  std::array<std::uint8_t, 4> srgba{};
  std::vector<std::array<float, 3>> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

struct ReadThreeMf {
  bool millimetre = false;
  std::string application;  // "Application" metadata, empty if none
  std::vector<std::string> metadata_keys;
  std::size_t build_items = 0;
  std::vector<ReadThreeMfObject> objects;
};

namespace detail {

inline void expect_ok(HRESULT result, const char* what) {
  if (result != LIB3MF_OK) throw std::runtime_error(std::string("lib3mf: ") + what + " failed");
}

// lib3mf's two-call string getters: size, then text.
template <typename Get>
std::string utf8(Get get) {
  ULONG needed = 0;
  expect_ok(get(nullptr, 0, &needed), "reading a string");
  std::string text(needed + 1, '\0');
  expect_ok(get(text.data(), needed + 1, &needed), "reading a string");
  text.resize(needed);
  return text;
}

}  // namespace detail

inline ReadThreeMf read_3mf(const std::filesystem::path& path) {
  using detail::expect_ok;
  ReadThreeMf package;
  io::Lib3mfObject model, reader, objects, items;
  expect_ok(NMR::lib3mf_createmodel(model.out<NMR::PLib3MFModel>()), "creating a model");
  auto* m = model.get<NMR::PLib3MFModel>();
  expect_ok(NMR::lib3mf_model_queryreader(m, "3mf", reader.out<NMR::PLib3MFModelReader>()),
            "creating the reader");
  expect_ok(NMR::lib3mf_reader_readfromfileutf8(reader.get<NMR::PLib3MFModelReader>(),
                                                path.c_str()),
            "reading the package");
  DWORD unit = 0;
  expect_ok(NMR::lib3mf_model_getunit(m, &unit), "reading the unit");
  package.millimetre = unit == NMR::MODELUNIT_MILLIMETER;
  DWORD metadata = 0;
  expect_ok(NMR::lib3mf_model_getmetadatacount(m, &metadata), "counting metadata");
  for (DWORD i = 0; i < metadata; ++i) {
    const std::string key = detail::utf8([&](LPSTR b, ULONG n, ULONG* need) {
      return NMR::lib3mf_model_getmetadatakeyutf8(m, i, b, n, need);
    });
    package.metadata_keys.push_back(key);
    if (key == "Application") {
      package.application = detail::utf8([&](LPSTR b, ULONG n, ULONG* need) {
        return NMR::lib3mf_model_getmetadatavalueutf8(m, i, b, n, need);
      });
    }
  }
  expect_ok(NMR::lib3mf_model_getbuilditems(m, items.out<NMR::PLib3MFModelBuildItemIterator>()),
            "listing the build");
  for (BOOL more = true;;) {
    expect_ok(NMR::lib3mf_builditemiterator_movenext(
                  items.get<NMR::PLib3MFModelBuildItemIterator>(), &more),
              "listing the build");
    if (!more) break;
    ++package.build_items;
  }
  expect_ok(NMR::lib3mf_model_getmeshobjects(m, objects.out<NMR::PLib3MFModelResourceIterator>()),
            "listing the objects");
  auto* it = objects.get<NMR::PLib3MFModelResourceIterator>();
  for (BOOL more = true;;) {
    expect_ok(NMR::lib3mf_resourceiterator_movenext(it, &more), "listing the objects");
    if (!more) break;
    io::Lib3mfObject resource, colour, group;
    expect_ok(NMR::lib3mf_resourceiterator_getcurrent(
                  it, resource.out<NMR::PLib3MFModelResource>()),
              "reading an object");
    auto* o = resource.get<NMR::PLib3MFModelMeshObject>();
    ReadThreeMfObject object;
    object.name = detail::utf8([&](LPSTR b, ULONG n, ULONG* need) {
      return NMR::lib3mf_object_getnameutf8(o, b, n, need);
    });
    DWORD vertices = 0, triangles = 0;
    expect_ok(NMR::lib3mf_meshobject_getvertexcount(o, &vertices), "counting vertices");
    expect_ok(NMR::lib3mf_meshobject_gettrianglecount(o, &triangles), "counting triangles");
    std::vector<NMR::MODELMESHVERTEX> v(vertices);
    std::vector<NMR::MODELMESHTRIANGLE> t(triangles);
    if (vertices > 0) {
      expect_ok(NMR::lib3mf_meshobject_getvertices(o, v.data(), vertices, nullptr),
                "reading vertices");
    }
    if (triangles > 0) {
      expect_ok(NMR::lib3mf_meshobject_gettriangleindices(o, t.data(), triangles, nullptr),
                "reading triangles");
    }
    for (const auto& p : v) {
      object.vertices.push_back({p.m_fPosition[0], p.m_fPosition[1], p.m_fPosition[2]});
    }
    for (const auto& i : t) {
      object.triangles.push_back({i.m_nIndices[0], i.m_nIndices[1], i.m_nIndices[2]});
    }
    expect_ok(NMR::lib3mf_object_createdefaultpropertyhandler(
                  o, colour.out<NMR::PLib3MFDefaultPropertyHandler>()),
              "reading the object's property");
    DWORD group_id = 0, index = 0;
    expect_ok(NMR::lib3mf_defaultpropertyhandler_getbasematerial(
                  colour.get<NMR::PLib3MFDefaultPropertyHandler>(), &group_id, &index),
              "reading the object's material");
    if (group_id != 0) {
      expect_ok(NMR::lib3mf_model_getbasematerialbyid(
                    m, group_id, group.out<NMR::PLib3MFModelBaseMaterial>()),
                "finding the material");
      auto* g = group.get<NMR::PLib3MFModelBaseMaterial>();
      expect_ok(NMR::lib3mf_basematerial_getdisplaycolor(g, index, &object.srgba[0],
                                                         &object.srgba[1], &object.srgba[2],
                                                         &object.srgba[3]),
                "reading the colour");
      object.material_name = detail::utf8([&](LPSTR b, ULONG n, ULONG* need) {
        return NMR::lib3mf_basematerial_getnameutf8(g, index, b, n, need);
      });
    }
    package.objects.push_back(std::move(object));
  }
  return package;
}

}  // namespace typemerge::test
