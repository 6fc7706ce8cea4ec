#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/mesh_checks.h"
#include "io/atomic_file.h"
#include "io/nrrd_writer.h"
#include "io/mesh_writers.h"
#include "io/stl_writer.h"
#include "support/scratch_files.h"

#include <zip.h>

namespace typemerge::io {
namespace {

namespace fs = std::filesystem;

using test::fresh_dir;
using test::read_file_bytes;

// A closed, outward tetrahedron:  3
//                                 |\   vertices 0..3 at the origin and the unit axes
//                                 0-2
//                                  \1
core::TriangleMesh tetrahedron() {
  core::TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

TEST(Stl, BinaryLayoutHeaderAndRoundTrip) {
  const fs::path file = fresh_dir("stl") / "tetra.stl";
  write_binary_stl(tetrahedron(), file, stl_header("1.2.3", "LPS"));
  const std::string bytes = read_file_bytes(file);
  ASSERT_EQ(bytes.size(), 84u + 50u * 4u);
  EXPECT_EQ(bytes.substr(0, 25), "typemerge 1.2.3 SPACE=LPS");
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  EXPECT_EQ(count, 4u);
  float normal[3];
  std::memcpy(normal, bytes.data() + 84, 12);  // first facet (0,2,1) faces −z
  EXPECT_FLOAT_EQ(normal[2], -1.0f);

  const core::TriangleMesh back = read_stl(file);
  EXPECT_EQ(back.positions.size(), 4u);  // corners welded back into shared vertices
  const core::MeshCheck check = core::check_mesh(back);
  EXPECT_TRUE(check.closed_manifold());
  EXPECT_NEAR(check.volume, 1.0 / 6.0, 1e-7);
  EXPECT_EQ(check.euler_characteristic, 2);
}

TEST(Stl, ReadsAsciiAndRejectsGarbage) {
  const fs::path dir = fresh_dir("ascii");
  std::ofstream(dir / "a.stl") << "solid t\n facet normal 0 0 1\n  outer loop\n"
                                  "   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1.5 0\n"
                                  "  endloop\n endfacet\nendsolid t\n";
  const core::TriangleMesh mesh = read_stl(dir / "a.stl");
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_FLOAT_EQ(mesh.positions[2][1], 1.5f);
  std::ofstream(dir / "b.stl") << "hello";
  EXPECT_THROW(read_stl(dir / "b.stl"), std::runtime_error);
}

TEST(AtomicFile, NothingAppearsUntilCommitAndNothingStaysOnAbort) {
  const fs::path dir = fresh_dir("atomic");
  std::ofstream(dir / "out.bin") << "previous";
  {
    AtomicFile file(dir / "out.bin");
    file.write("new content");
    EXPECT_EQ(read_file_bytes(dir / "out.bin"), "previous");  // the old file is intact meanwhile
  }  // destroyed without commit: as if the run had failed
  EXPECT_EQ(read_file_bytes(dir / "out.bin"), "previous");
  const auto entries = std::distance(fs::directory_iterator(dir), fs::directory_iterator());
  EXPECT_EQ(entries, 1);  // no temporary left behind

  AtomicFile file(dir / "out.bin");
  file.write("new content");
  file.commit();
  EXPECT_EQ(read_file_bytes(dir / "out.bin"), "new content");
  EXPECT_THROW(AtomicFile(dir / "missing_folder" / "x"), std::runtime_error);
}

// The temporary files of a target no process holds (a killed run's) go when the target is
// written again; one a live writer holds stays, and so do names of other targets or of
// another form.
TEST(AtomicFile, AKilledRunsTemporaryFileGoesWithTheNextWrite) {
  const fs::path dir = fresh_dir("atomic_stale");
  const std::vector<std::string> kept_names = {".other.bin.ghi789.partial", ".out.bin.partial",
                                               "out.bin.jkl012.partial", ".out.bin.mno345"};
  for (const std::string& name : kept_names) std::ofstream(dir / name) << "not ours";
  std::ofstream(dir / ".out.bin.abc123.partial") << "killed";
  std::ofstream(dir / ".out.bin.def456.partial") << "live";
  const int live = ::open((dir / ".out.bin.def456.partial").c_str(), O_RDONLY);
  ASSERT_GE(live, 0);
  ASSERT_EQ(::flock(live, LOCK_EX | LOCK_NB), 0);
  auto temporaries = [&] {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind(".out.bin.", 0) == 0 && name.size() == 23 && name.ends_with(".partial")) {
        names.push_back(name);
      }
    }
    return names;
  };
  {
    AtomicFile file(dir / "out.bin");
    EXPECT_FALSE(fs::exists(dir / ".out.bin.abc123.partial"));
    EXPECT_TRUE(fs::exists(dir / ".out.bin.def456.partial"));
    EXPECT_EQ(temporaries().size(), 2u);  // the live one and this writer's own
    file.write("new");
    file.commit();
  }
  EXPECT_EQ(read_file_bytes(dir / "out.bin"), "new");
  EXPECT_EQ(temporaries(), std::vector<std::string>{".out.bin.def456.partial"});
  ::close(live);  // its writer "dies": the next write removes it
  {
    AtomicFile file(dir / "out.bin");
    file.commit();
  }
  EXPECT_TRUE(temporaries().empty());
  for (const std::string& name : kept_names) EXPECT_TRUE(fs::exists(dir / name)) << name;
}

TEST(Nrrd, HeaderCarriesTheShearedGeometryAndSamplesFollow) {
  core::IndexToPatient geometry;
  geometry.origin = {1.5, -2, 3};
  geometry.axes = {{{0.5, 0, 0}, {0, 0.5, 0}, {0, 1.25, 4}}};  // a tilted slice step
  core::Volume volume({2, 3, 4}, geometry);
  for (std::size_t v = 0; v < volume.samples().size(); ++v) {
    volume.samples()[v] = static_cast<float>(v) - 10.25f;
  }
  const fs::path dir = fresh_dir("nrrd");
  write_nrrd(volume, dir / "f.nrrd", NrrdSampleType::float32);
  write_nrrd(volume, dir / "i.nrrd", NrrdSampleType::int16);
  const std::string f = read_file_bytes(dir / "f.nrrd");
  const std::size_t end = f.find("\n\n");
  ASSERT_NE(end, std::string::npos);
  EXPECT_NE(f.find("space directions: (0.5,0,0) (0,0.5,0) (0,1.25,4)"), std::string::npos);
  EXPECT_NE(f.find("space origin: (1.5,-2,3)"), std::string::npos);
  EXPECT_NE(f.find("sizes: 2 3 4"), std::string::npos);
  ASSERT_EQ(f.size() - end - 2, 24u * 4u);
  float last = 0;
  std::memcpy(&last, f.data() + f.size() - 4, 4);
  EXPECT_FLOAT_EQ(last, 23 - 10.25f);
  const std::string i = read_file_bytes(dir / "i.nrrd");
  std::int16_t first = 0;
  std::memcpy(&first, i.data() + i.find("\n\n") + 2, 2);
  EXPECT_EQ(first, -10);  // rounded to the nearest HU
}

// Read back independently of lib3mf, with libzip: the package's model part, its unit, every
// vertex and every triangle. (lib3mf's own reader leaks inside libzip under LeakSanitizer.)
TEST(ThreeMf, PackageHoldsTheMeshInMillimetres) {
  const fs::path file = fresh_dir("3mf") / "tetra.3mf";
  ASSERT_EQ(mesh_format_for(file, false), MeshFormat::three_mf);
  core::TriangleMesh mesh = tetrahedron();
  for (auto& p : mesh.positions) p[0] += 12.5f;
  write_mesh(mesh, file, MeshFormat::three_mf, "typemerge test");
  for (const auto& entry : fs::directory_iterator(file.parent_path())) {
    EXPECT_EQ(entry.path().extension(), ".3mf") << "left over: " << entry.path();
  }

  int error = 0;
  zip_t* archive = zip_open(file.c_str(), ZIP_RDONLY, &error);
  ASSERT_NE(archive, nullptr) << "not a zip package, libzip error " << error;
  zip_stat_t stat;
  ASSERT_EQ(zip_stat(archive, "3D/3dmodel.model", 0, &stat), 0);
  std::string model(stat.size, '\0');
  zip_file_t* part = zip_fopen(archive, "3D/3dmodel.model", 0);
  ASSERT_NE(part, nullptr);
  EXPECT_EQ(zip_fread(part, model.data(), stat.size), static_cast<zip_int64_t>(stat.size));
  zip_fclose(part);
  EXPECT_EQ(zip_name_locate(archive, "[Content_Types].xml", 0) >= 0, true);
  zip_close(archive);

  EXPECT_NE(model.find("unit=\"millimeter\""), std::string::npos);
  auto count = [&](const std::string& what) {
    std::size_t n = 0;
    for (std::size_t at = model.find(what); at != std::string::npos; at = model.find(what, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("<vertex "), 4u);
  EXPECT_EQ(count("<triangle "), 4u);
  EXPECT_NE(model.find("<vertex x=\"13.500000\" y=\"0\" z=\"0\""), std::string::npos) << model;
  EXPECT_NE(model.find("<triangle v1=\"1\" v2=\"2\" v3=\"3\""), std::string::npos) << model;
  // Byte-identical when written again (lib3mf's own UUIDs would be random).
  const std::string first = read_file_bytes(file);
  write_mesh(mesh, file, MeshFormat::three_mf, "typemerge test");
  EXPECT_EQ(read_file_bytes(file), first);
}

}  // namespace
}  // namespace typemerge::io
