// Which files are DICOM at all (issue 16, item 2): without the DICM magic a file is DICOM only
// if it starts like a data set; text files (README, LICENSE, notes) are "not DICOM", not
// damaged DICOM, while a DICM preamble followed by garbage is a damaged DICOM file, and a bare
// data set without preamble or meta header is still read.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "ct_writer/ct_writer.h"
#include "dicom/header_reader.h"
#include "support/scratch_files.h"

namespace {

namespace fs = std::filesystem;
using namespace typemerge::dicom;
namespace ct_writer = typemerge::ct_writer;

// This process's scratch folder (removed when it ends).
const fs::path& scratch() {
  static const fs::path dir = typemerge::test::fresh_dir("file_kind");
  return dir;
}

fs::path write_temp(const std::string& name, const std::string& bytes) {
  const fs::path file = scratch() / name;
  std::ofstream(file, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return file;
}

TEST(FileKind, TextFilesAreNotDicom) {
  const std::string texts[] = {
      "# typemerge\n\nA C++ tool that turns a CT scan into a printable surface.\n",
      "MIT License\n\nCopyright (c) 2026\n",
      "Clark K, Vendt B, Smith K, et al. The Cancer Imaging Archive (TCIA).\n",
      "x,y,z\n1,2,3\n",
      "ab",
      "",
      std::string(300, '\xff'),
  };
  int k = 0;
  for (const std::string& text : texts) {
    SCOPED_TRACE(k);
    const HeaderReadResult read = read_headers(write_temp("text" + std::to_string(k++), text), {});
    EXPECT_EQ(read.kind, FileKind::not_dicom) << read.skip_reason;
    EXPECT_TRUE(read.frames.empty());
    EXPECT_NE(read.skip_reason.find("not a DICOM file"), std::string::npos) << read.skip_reason;
  }
}

TEST(FileKind, APreambleThenGarbageIsDamagedDicom) {
  std::string bytes(128, '\0');
  bytes += "DICM";
  bytes += std::string("\x02\x00\x10\x00UI\xff\x7f", 8);  // a meta element longer than the file
  bytes += "garbage garbage garbage";
  const HeaderReadResult read = read_headers(write_temp("preamble_garbage", bytes), {});
  EXPECT_EQ(read.kind, FileKind::unreadable) << read.skip_reason;
  EXPECT_TRUE(read.frames.empty());
}

TEST(FileKind, BareDataSetsAreStillRead) {
  for (const auto syntax : {ct_writer::TransferSyntax::implicit_little,
                            ct_writer::TransferSyntax::explicit_little,
                            ct_writer::TransferSyntax::explicit_big}) {
    for (const auto container : {ct_writer::Container::dataset_only,
                                 ct_writer::Container::no_preamble}) {
      SCOPED_TRACE(testing::Message() << ct_writer::to_uid(syntax) << " container "
                                      << static_cast<int>(container));
      ct_writer::CtSliceSpec spec;
      spec.transfer_syntax = syntax;
      spec.container = container;
      const fs::path file = scratch() / "bare.dcm";
      ct_writer::write_ct_slice(spec, file);
      const HeaderReadResult read = read_headers(file, {});
      EXPECT_EQ(read.kind, FileKind::ct_image) << read.skip_reason;
      EXPECT_EQ(read.frames.size(), 1u) << read.skip_reason;
    }
  }
}

}  // namespace

// The batch names the modality that alone refused a file ("4 MR images, not CT (use
// --allow-non-ct)"), without parsing the reason's text; other refusals leave it empty.
TEST(FileKind, TheRefusedModalityIsGivenOnlyWhenItAloneRefusedTheFile) {
  ct_writer::CtSliceSpec mr;
  mr.sop_class_uid = "1.2.840.10008.5.1.4.1.1.4";  // MR Image Storage
  mr.modality = "MR";
  const fs::path file = scratch() / "mr";
  ct_writer::write_ct_slice(mr, file);
  HeaderReadResult read = read_headers(file, {});
  EXPECT_EQ(read.kind, FileKind::other_image);
  EXPECT_EQ(read.refused_modality, "MR") << read.skip_reason;
  read = read_headers(file, {.allow_non_ct_modality = true});
  EXPECT_TRUE(read.skip_reason.empty()) << read.skip_reason;
  EXPECT_TRUE(read.refused_modality.empty());

  ct_writer::CtSliceSpec secondary = mr;
  secondary.sop_class_uid = "1.2.840.10008.5.1.4.1.1.7";  // Secondary Capture, modality MR
  ct_writer::write_ct_slice(secondary, file);
  read = read_headers(file, {});
  EXPECT_EQ(read.skip_reason, "secondary capture image");
  EXPECT_TRUE(read.refused_modality.empty());
  std::string damaged(128, '\0');
  damaged += "DICM";
  damaged += std::string("\x02\x00\x10\x00UI\xff\x7f", 8);  // as in APreambleThenGarbage...
  damaged += "garbage";
  read = read_headers(write_temp("refused_modality_damaged", damaged), {});
  EXPECT_EQ(read.kind, FileKind::unreadable);
  EXPECT_TRUE(read.refused_modality.empty());
}
