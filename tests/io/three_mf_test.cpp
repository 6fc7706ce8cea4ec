// write_3mf's packages read back with lib3mf: several named, coloured objects in one frame,
// every vertex and triangle as given, and the same bytes on every run (no time stamp, no random
// UUID). io_test.cpp reads a package independently of lib3mf (libzip, the XML as text).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "io/three_mf_writer.h"
#include "support/scratch_files.h"
#include "support/three_mf_reader.h"

namespace typemerge::io {
namespace {

namespace fs = std::filesystem;

using test::fresh_dir;
using test::read_file_bytes;

// A closed, outward tetrahedron:  3
//                                 |\   vertices 0..3 at `origin` and `size` along the axes;
//                                 0-2  coordinates with few binary and decimal digits, so
//                                  \1  the package's text holds them exactly
core::TriangleMesh tetrahedron(std::array<float, 3> origin, float size) {
  core::TriangleMesh mesh;
  mesh.positions = {origin, origin, origin, origin};
  for (int c = 0; c < 3; ++c) mesh.positions[c + 1][c] += size;
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

// The 2-byte little-endian fields at `offset` after every `signature` in the zip's bytes.
std::vector<std::uint32_t> fields_after(const std::string& zip, const char* signature,
                                        std::size_t offset) {
  std::vector<std::uint32_t> values;
  for (std::size_t at = zip.find(signature, 0, 4); at != std::string::npos;
       at = zip.find(signature, at + 4, 4)) {
    std::uint32_t value = 0;
    std::memcpy(&value, zip.data() + at + offset, 4);
    values.push_back(value);
  }
  return values;
}

TEST(ThreeMfPackage, ObjectsKeepTheirNamesColoursAndGeometry) {
  const fs::path file = fresh_dir("parts") / "head.3mf";
  // A small "bone" inside a larger "skin": the objects overlap, as nested tissues do.
  const core::TriangleMesh inner = tetrahedron({-3.75f, 12.25f, 100.5f}, 2.5f);
  const core::TriangleMesh outer = tetrahedron({-5.0f, 10.0f, 99.0f}, 8.0f);
  write_3mf({{&inner, "bone", {0xE3, 0xDA, 0xC9}}, {&outer, "skin", {0xD2, 0xB4, 0x8C}}}, file,
            "typemerge test SPACE=LPS");
  for (const auto& entry : fs::directory_iterator(file.parent_path())) {
    EXPECT_EQ(entry.path().filename(), "head.3mf") << "left over: " << entry.path();
  }

  const test::ReadThreeMf package = test::read_3mf(file);
  EXPECT_TRUE(package.millimetre);
  EXPECT_EQ(package.application, "typemerge test SPACE=LPS");
  EXPECT_EQ(package.metadata_keys, std::vector<std::string>{"Application"});  // no date
  EXPECT_EQ(package.build_items, 2u);
  ASSERT_EQ(package.objects.size(), 2u);
  const core::TriangleMesh* meshes[2] = {&inner, &outer};
  const char* names[2] = {"bone", "skin"};
  const std::array<std::uint8_t, 4> colours[2] = {{0xE3, 0xDA, 0xC9, 0xFF},
                                                  {0xD2, 0xB4, 0x8C, 0xFF}};
  for (int o = 0; o < 2; ++o) {
    const test::ReadThreeMfObject& object = package.objects[o];
    EXPECT_EQ(object.name, names[o]);
    EXPECT_EQ(object.material_name, names[o]);
    EXPECT_EQ(object.srgba, colours[o]) << names[o];
    EXPECT_EQ(object.vertices, meshes[o]->positions) << names[o];
    EXPECT_EQ(object.triangles, meshes[o]->triangles) << names[o];
  }
}

TEST(ThreeMfPackage, SamePartsGiveTheSameBytesAndNoTimeStamps) {
  const fs::path dir = fresh_dir("bytes");
  const core::TriangleMesh a = tetrahedron({0, 0, 0}, 1);
  const core::TriangleMesh b = tetrahedron({0.5f, 0.5f, 0.5f}, 1);
  const std::vector<ThreeMfPart> parts = {{&a, "bone", {1, 2, 3}}, {&b, "skin", {4, 5, 6}}};
  write_3mf(parts, dir / "first.3mf", "typemerge test");
  sleep(2);  // a zip time stamp has a resolution of 2 s
  write_3mf(parts, dir / "second.3mf", "typemerge test");
  const std::string first = read_file_bytes(dir / "first.3mf");
  ASSERT_GT(first.size(), 100u);
  EXPECT_EQ(read_file_bytes(dir / "second.3mf"), first);
  // The modification time and date of every entry, in its local header (offset 10) and in the
  // central directory (offset 12), are zero: nothing of the clock reaches the package.
  const auto local = fields_after(first, "PK\x03\x04", 10);
  const auto central = fields_after(first, "PK\x01\x02", 12);
  EXPECT_GE(local.size(), 3u);  // content types, relationships, model
  EXPECT_EQ(local.size(), central.size());
  for (std::uint32_t stamp : local) EXPECT_EQ(stamp, 0u);
  for (std::uint32_t stamp : central) EXPECT_EQ(stamp, 0u);

  // Other content, other bytes (the UUIDs follow the content): a colour, a name, a vertex.
  auto bytes_with = [&](std::vector<ThreeMfPart> changed, const std::string& name) {
    write_3mf(changed, dir / name, "typemerge test");
    return read_file_bytes(dir / name);
  };
  std::vector<ThreeMfPart> recoloured = parts;
  recoloured[1].srgb[2] = 7;
  EXPECT_NE(bytes_with(recoloured, "recoloured.3mf"), first);
  std::vector<ThreeMfPart> renamed = parts;
  renamed[0].name = "teeth";
  EXPECT_NE(bytes_with(renamed, "renamed.3mf"), first);
}

TEST(ThreeMfPackage, IdenticalPartsStayTwoObjects) {
  // Two presets can give the same surface; their objects still need distinct UUIDs.
  const fs::path file = fresh_dir("twins") / "twins.3mf";
  const core::TriangleMesh mesh = tetrahedron({0, 0, 0}, 1);
  write_3mf({{&mesh, "bone", {1, 1, 1}}, {&mesh, "bone", {1, 1, 1}}}, file, "typemerge test");
  const test::ReadThreeMf package = test::read_3mf(file);
  ASSERT_EQ(package.objects.size(), 2u);
  EXPECT_EQ(package.objects[0].vertices, package.objects[1].vertices);
  EXPECT_EQ(package.build_items, 2u);
}

TEST(ThreeMfPackage, AnUnwritableFolderThrowsAndLeavesNothing) {
  const fs::path dir = fresh_dir("unwritable");
  const core::TriangleMesh mesh = tetrahedron({0, 0, 0}, 1);
  EXPECT_THROW(write_3mf({{&mesh, "bone", {1, 1, 1}}}, dir / "missing" / "x.3mf", "t"),
               std::runtime_error);
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace
}  // namespace typemerge::io
