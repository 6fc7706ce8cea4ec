// The input tree is never written (issue 6): every file and folder of a generated study keeps
// its bytes, size, modification time and permissions through info, volume and convert.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <filesystem>
#include <map>
#include <string>

#include "app/cli_runner.h"
#include "app/study_tree.h"
#include "ct_writer/ct_writer.h"

namespace {

namespace fs = std::filesystem;
namespace ctw = typemerge::ct_writer;
using typemerge::test::fresh_dir;
using typemerge::test::read_file_bytes;
using typemerge::test::run_cli;

struct Entry {
  char type = '?';
  std::uintmax_t size = 0;
  std::uint64_t hash = 0;
  std::int64_t mtime_ns = 0;
  unsigned mode = 0;
  bool operator==(const Entry&) const = default;
};

std::ostream& operator<<(std::ostream& out, const Entry& e) {
  return out << e.type << " size " << e.size << " hash " << e.hash << " mtime " << e.mtime_ns
             << " mode " << std::oct << e.mode << std::dec;
}

// The root itself ("") and everything below it, symlinks not followed.
std::map<std::string, Entry> snapshot(const fs::path& root) {
  std::map<std::string, Entry> entries;
  auto add = [&](const fs::path& path) {
    struct stat info {};
    if (::lstat(path.c_str(), &info) != 0) {
      ADD_FAILURE() << "cannot stat " << path;
      return;
    }
    Entry e;
    e.type = S_ISDIR(info.st_mode) ? 'd' : S_ISLNK(info.st_mode) ? 'l' : S_ISREG(info.st_mode) ? 'f' : '?';
    e.size = static_cast<std::uintmax_t>(info.st_size);
    e.mode = info.st_mode & 07777;
    e.mtime_ns = std::int64_t{info.st_mtim.tv_sec} * 1000000000 + info.st_mtim.tv_nsec;
    if (e.type == 'f') e.hash = ctw::fnv1a64(read_file_bytes(path));
    if (e.type == 'l') e.hash = ctw::fnv1a64(fs::read_symlink(path).string());
    entries[path.lexically_relative(root).string()] = e;
  };
  add(root);
  for (const auto& entry : fs::recursive_directory_iterator(root)) add(entry.path());
  return entries;
}

TEST(InputTree, CommandsLeaveEveryFileAndFolderAsTheyWere) {
  const fs::path study = fresh_dir("untouched_study");
  ctw::SeriesLayout layout;
  layout.uid_seed = "untouched";
  layout.columns = 20;
  layout.rows = 20;
  layout.slices = 10;
  layout.hu = [](int i, int j, int k) {
    return std::hypot(i - 9.5, j - 9.5, k - 4.5) < 5 ? 1000.0 : -1000.0;
  };
  // A study as an archive gives it: nested folders, a read-only file and folder, a file that
  // is not DICOM, a symlink, a second (localizer-like single-slice) series.
  const auto specs = ctw::make_axial_series(layout);
  for (std::size_t k = 0; k < specs.size(); ++k) {
    const fs::path folder = study / "patient" / (k < 5 ? "part1" : "part2");
    fs::create_directories(folder);
    ctw::write_ct_slice(specs[k], folder / ("IM" + std::to_string(k)));
  }
  ctw::CtSliceSpec scout;
  scout.series_instance_uid = ctw::make_uid("untouched/scout");
  scout.image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
  ctw::write_ct_slice(scout, study / "patient" / "scout.dcm");
  { std::ofstream(study / "patient" / "notes.txt") << "not DICOM\n"; }
  // Folders no study comes of, which batch lists (issue 16): damaged copies, a folder of notes.
  typemerge::test::write_damaged_dicom(study / "patient" / "damaged" / "IM_broken");
  typemerge::test::write_truncated_copy(study / "patient" / "part1" / "IM0",
                                        study / "patient" / "damaged" / "IM_cut");
  fs::create_directories(study / "patient" / "docs");
  { std::ofstream(study / "patient" / "docs" / "readme.txt") << "not DICOM either\n"; }
  fs::create_symlink("part1", study / "patient" / "link_to_part1");
  fs::permissions(study / "patient" / "part2" / "IM7", fs::perms::owner_read | fs::perms::group_read);
  fs::permissions(study / "patient" / "part2",
                  fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                      fs::perms::group_exec);
  // Modification times in the past, so that a rewrite in the same second would still show.
  for (const auto& entry : fs::recursive_directory_iterator(study)) {
    if (!entry.is_symlink()) {
      fs::last_write_time(entry.path(), fs::file_time_type::clock::now() - std::chrono::hours(24));
    }
  }

  const auto before = snapshot(study);
  ASSERT_GE(before.size(), 15u);
  const fs::path out = fresh_dir("untouched_out");
  const std::string in = study.string();
  for (const std::string& command : {
           "info " + in,
           "info --json --list-skipped " + in,
           "info --follow-symlinks " + in,
           "volume " + in + " -o " + (out / "v.nrrd").string(),
           "convert " + in + " --preset bone,skin -o " + (out / "s").string() +
               " --preview --report " + (out / "r.json").string(),
           "convert " + in + " --iso 0 --algorithm mc --finish none -o " +
               (out / "mc.stl").string(),
           "batch " + in + " --preset bone --out " + (out / "batch").string() + " --jobs 2",
           "batch " + in + " --preset bone --out " + (out / "batch").string(),  // rerun: skips
           "convert " + in + " --preset bone,skin --center -o " + (out / "s.3mf").string(),
           "batch " + in + " --preset bone,skin --format 3mf --out " + (out / "batch_3mf").string(),
           "convert " + in + " --iso auto --hollow 2 -o " + (out / "hollow.stl").string() +
               " --report " + (out / "hollow.json").string(),
       }) {
    const auto r = run_cli(command);
    // The tree holds a localizer-only study and damaged files too: batch says "some failed"
    // (5) for them.
    EXPECT_EQ(r.exit_code, command.rfind("batch", 0) == 0 ? 5 : 0) << command << "\n" << r.out
                                                                   << r.err;
  }
  // The batch did read the folders without a study (and, above, left them as they were).
  const std::string summary = read_file_bytes(out / "batch" / "summary.json");
  EXPECT_NE(summary.find("\"no_study\": 1,"), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"no_ct\": 1"), std::string::npos) << summary;
  const auto after = snapshot(study);
  EXPECT_EQ(after.size(), before.size());
  for (const auto& [path, entry] : before) {
    const auto found = after.find(path);
    if (found == after.end()) {
      ADD_FAILURE() << "removed: " << path;
      continue;
    }
    EXPECT_EQ(found->second, entry) << "changed: '" << path << "'";
  }
  for (const auto& [path, entry] : after) {
    EXPECT_TRUE(before.count(path)) << "created in the input tree: " << path;
  }
  // Restore write permission so the next run can delete the tree.
  fs::permissions(study / "patient" / "part2", fs::perms::owner_all);
}

}  // namespace
