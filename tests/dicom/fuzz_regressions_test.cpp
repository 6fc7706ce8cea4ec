// Inputs found by the fuzz targets (fuzz/), replayed: each failed before its fix.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ct_writer/ct_writer.h"
#include "dicom/header_reader.h"
#include "dicom/pixel_reader.h"
#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "dicom/slice_geometry.h"
#include "support/scratch_files.h"

namespace {

namespace fs = std::filesystem;
using namespace typemerge::dicom;

std::string from_hex(const std::string& hex) {
  std::string bytes;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) {
    bytes.push_back(static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  }
  return bytes;
}

// This process's scratch folder (removed when it ends).
const fs::path& scratch() {
  static const fs::path dir = typemerge::test::fresh_dir("fuzz_regression");
  return dir;
}

fs::path write_temp(const std::string& name, const std::string& bytes) {
  const fs::path file = scratch() / name;
  std::ofstream(file, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return file;
}

// Writes a replayed file and reads its headers as the scan does: no frame may come out, and
// the reason must contain `reason`. The result is returned for further checks.
HeaderReadResult read_refused(const std::string& name, const std::string& bytes,
                              const std::string& reason) {
  HeaderReadResult read = read_headers(write_temp(name, bytes), {});
  EXPECT_TRUE(read.frames.empty());
  EXPECT_NE(read.skip_reason.find(reason), std::string::npos) << read.skip_reason;
  return read;
}

// fuzz_dicom_file, oom-3b2b5c89…: a 951-byte file whose header declares a 2.4 GB value.
// DCMTK allocated the declared length on first access to the value (libFuzzer: malloc of
// 2466250779 bytes in DcmByteString::newValueField from read_headers). Now refused before
// any value is read.
TEST(FuzzRegressions, HugeDeclaredValueLengthIsRefusedBeforeAllocating) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b2000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491200"
    "312e322e3834302e31303030382e312e32000200120055492000312e322e3832362e302e312e333638303034332e3130"
    "2e313233342e302e31000200130053481000545950454d474552455f4354575f312008000800160000004f524947494e"
    "414c5c5052494d4152595c415849414c080016001a000093939393939393939393939393939393939393939393939393"
    "939393939393939393939393939393939393939393939393939393939393939393939393939393939393939393939393"
    "93939393939393939393939393939393939393939393939393939393939300312e322e3834302e31303030382e352e31"
    "2e342e312e312e32000800180020000000312e322e3832362e302e312e333638303034332e31302e313233342e312e31"
    "000800200008000000323030303031303108003000060000003030303030300800500000000000080060000200000043"
    "540800700014000000747970656d657267652063745f777269746572200800900000000000080030101000000053796e"
    "7468657469632073747564792008003e100c00000053796e746865746963204354100010001200000053796e74686574"
    "69635e5068616e746f6d20100020000a00000053594e5448455449432010003000080000003139303030313031100040"
    "00020000004f201800500002000000312018006000040000003132302018000051040000004846532020000d00200000"
    "00312e322e3832362e302e312e333638303034332e31302e313233342e312e320020000e0020000000312e322e383236"
    "2e302e312e333638303034332e31302e313233342e312e33002000ff1dffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffff0000002d313032342028005310020000003120e0"
    "7f1000200000000000c900900158022003e803b004780540060807d00798086009280af00ab80b"
  );
  ASSERT_EQ(reproducer.size(), 951u);
  const HeaderReadResult read = read_refused("oom.dcm", reproducer, "declares");
  EXPECT_EQ(read.kind, FileKind::unreadable);
}

// fuzz_dicom_file, oom-e93235e3…: a 587-byte file whose SOPClassUID is an SV element of
// undefined length. DCMTK took the length as 4 GB and allocated it when the value was read as
// text (libFuzzer: malloc of 4294967296 bytes in DcmElement::getOFStringArray from
// read_headers). Now refused before any value is read.
TEST(FuzzRegressions, UndefinedLengthOnAPlainValueIsRefused) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000ff0000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b4000000"
    "020001004f4200000200000000010200020055491a00302e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491400"
    "312e322e3834302e31303030382e312e322e31000200120055492000312e322e3832362e302e312e333638303034332e"
    "31302e313233352e302e31000200130053481000545950454d455247455f4354575f312008000800435316004f524947"
    "494e414c5c5052494d4152595c415849414c0800160053561affffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffff00312e322e3834302e31303030382e352e312e342e312e312e32000800180055492000312e322e383236"
    "2e302e312e3336383030003e104c4f0c0053796e74686574696320435410001000504e120053796e7468657469635e50"
    "68616e746f6d100055491400312e322e3834302e31303030382e312e322e31000200120055492000312e322e3832362e"
    "302e312e333638303034332e31302e313233342e302e31000200130053481000545950454d455247455f4354575f3120"
    "0800084453040031320030"
  );
  ASSERT_EQ(reproducer.size(), 587u);
  const HeaderReadResult read =
      read_refused("undefined_length.dcm", reproducer, "undefined length");
  EXPECT_EQ(read.kind, FileKind::unreadable);
}

// fuzz_dicom_file, oom-4b468274…: a 755-byte deflated file whose inflated data set declares
// a 3.3 GB value. DCMTK reads a deflated stream in one pass, allocating each value as it goes
// (libFuzzer: malloc of 3358654466 bytes in DcmElement::newValueField from loadFile), before
// check_value_lengths could look. Now the prescan, which inflates the data set anyway,
// refuses it before DCMTK parses.
TEST(FuzzRegressions, DeflatedValueLongerThanTheDataSetIsRefusedBeforeParsing) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e312e39390200120055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e31000200130053481000545950454d455247455f4354575f31208d90cd6ed34014854f7e"
    "688734a0694155c56a96d960cd386e091b54cb2dd8929309b62b5ac982a062b55db454c18866d557e892c760c923b0e4"
    "1158b2e41138b6a5c0326359fae6dc7367ce5c018120dd864da257d1c48ff369128dfde424f78f233f16d8c651f404c6"
    "719d91a71da3b51e39bb8e713cfe54d9bd43876a1cee9e438f33dc1b69ed0de9768c3bac9df4291cf8022e4fd0461b01"
    "8d6cbc065d2f8129d21074cd98a68d2013b8466c1fa35c5c1797c5fcac50a7e5bb2ff38bb2982b813b4c27955bcbd84a"
    "a48babf2bc282f4ed5a7f2f38705eb2fa8f7ffd3834c42b267eb9ff6767afefeaafc78a92493c5b687f4649285875914"
    "50d17556f3bcc92ab15fa7b26a87390f4886342375615c4dc6eb801cbe4c95c28315e6e1f2ce872bf886f4f17d6175a3"
    "c226a2b4a1ad253d5a92cb3c9c67ce8fbb67dcf561f27a9f9b5a4b56b8d1c3006d1cf1cc16a9cb77f731b6131b84891d"
    "1fba6ac03c55b5cbeae69274338bdcb08e56a54aaaad9afad589356d903a358194c82aef53a35d8f5da96ce6faeb56c2"
    "be01df5dad1fb86b1db755e777e75b5de6defe9a58ffffffff02ee0f7a7f7adf37fe02"
  );
  ASSERT_EQ(reproducer.size(), 755u);
  const HeaderReadResult read =
      read_refused("deflated_oom.dcm", reproducer, "refused before parsing");
  EXPECT_NE(read.skip_reason.find("declares"), std::string::npos) << read.skip_reason;
}

// fuzz_dicom_file, oom (found 2026-12-01): an 870-byte file whose meta header names the
// transfer syntax twice, deflate first and explicit little endian second. DCMTK keeps the
// first and inflates; the prescan took the second, walked the compressed bytes as explicit VR
// and let through an inflated OB pixel value declaring 3,760,206,132 bytes (libFuzzer: malloc
// in DcmPixelData::read from loadFile). Now the prescan keeps the first, like DCMTK, and a
// meta header with a repeated or out-of-order element is not trusted before deflated data.
TEST(FuzzRegressions, RepeatedTransferSyntaxInFrontOfDeflatedDataIsRefusedBeforeParsing) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e312e39390200100055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e31000200130053481000545950454d455247455f4354575f31208d90cd6ed34014854f7e"
    "688734a0694155c56a96d960cd386e091b54cb2dd8929309b62b5ac982a062b55db454c18866d557e892c760c923b0e4"
    "1158b2e41138b6a5c0326359fae6dc7367ce5c018120dd864da257d1c48ff369128dfde424f78f233f16d8c651f404c6"
    "719d91a71da3b51e39bb8e713cfe54d9bd43876a1cee9e438f33dc1b69ed0de9768c3bac9df4291cf8022e4fd0461b01"
    "8d6cbc065d2f8129d21074cd98a68d2013b8466c1fa35c5c1797c5fcac50a7e5bb2ff38bb2982b813b4c27955bcbd84a"
    "a48babf2bc282f4ed5a7f2f38705eb2fa8f7ffd3834c42b267eb9ff6767afefeaafc78a92493c5b687f4649285875914"
    "50d17556f3bcc92ab15fa7b26a87390f4886342375615c4dc6eb801cbe4c95c28315e6e1f2ce872bf886f4f17d6175a3"
    "c226a2b4a1ad253d5a92cb3c9c67ce8fbb67dcf561f27a9f9b5a4b56b8d1c3006d1cf1cc16a9cb77f731b6131b84891d"
    "1fba6ac03c55b5cbeae69274338bdcb08e56a54aaaad9afad589356d903a358194c82aef53a35d8f5da96ce6faeb56c2"
    "be01bc065d2f8129d21074cd98a68d2013b8466c1fa35c5c1797c5fcac50a7e5bb2ff38bb2982b813b4c27955bcbd84a"
    "a48babf2bc282f4ed5a7f2f38705eb2fa8f7ffd3834c42b267eb9ff6767afefeaafc78a92493c5b687f4649285875914"
    "50d17556f3bcc92ab15fa7b26a87390f4886342375df5dad1fb86b1db755e777e75bf7e6003000445304fe55ccee0f7a"
    "7f7adf37fe02"
  );
  ASSERT_EQ(reproducer.size(), 870u);
  const HeaderReadResult read =
      read_refused("repeated_syntax_oom.dcm", reproducer, "refused before parsing");
  EXPECT_NE(read.skip_reason.find("deflated"), std::string::npos) << read.skip_reason;
  EXPECT_EQ(read.kind, FileKind::unreadable);
}

// fuzz_dicom_file, oom-1987f38f…: the same in a 725-byte deflated file whose meta header
// holds an element of another group inside the length its group length declares. DCMTK
// starts the data set where that length ends; the prescan stopped at the foreign group,
// inflated from the wrong byte, found nothing, and DCMTK then allocated 3.9 GB.
TEST(FuzzRegressions, MetaHeaderEndsWhereItsGroupLengthSays) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e312e39390200120055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e31007e00130053481000545950454d455247455f4354575f31208d90cd6ed34014854f7e"
    "688734a0694155c56a96d960cd386e091b54cb2dd8929309b62b5ac982a062b55db454c18866d557e892c760c923b0e4"
    "1158b2e41138b6a5c0326359fae6dc7367ce5c018120dd86000000000000000000ffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff01000008ffffffffffffffff"
    "ffffffffffffffff32fffffffffffffffffffffff7ffffffffffffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffb0bdffffffffffffffffffffffffffff"
    "fffffffffffffffefeaafc78a92493c5b687f464928587591450d17556f3bcc92ab15fa7f4f17d6175a3c226a2b45549"
    "a1ad253d1a"
  );
  ASSERT_EQ(reproducer.size(), 725u);
  read_refused("meta_length_oom.dcm", reproducer, "refused before parsing");
}

// fuzz_dicom_file, oom-84b1836d…: a 603-byte deflated file whose meta header has an element
// with a VR of two non-letter bytes. DCMTK reads that with a 2-byte length (EVR_UNKNOWN2B)
// and goes on to the transfer syntax; the prescan stopped there, missed "deflated" and let
// DCMTK allocate 3.1 GB from the inflated data set.
TEST(FuzzRegressions, NonLetterVrIsReadWithATwoByteLengthAsDcmtkDoes) {
  const std::string reproducer = from_hex(
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055df2000312e322e3832362e302e312f333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e312e39390200120055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e31000200130053481000545950454d455247455f4354575f31208d90cd6ed34014854f7e"
    "688734a0694155c56a96d960cd386e091b54cb2dd8929309b62b5ac982a062b55db454c18866d557e892c760c923b0e4"
    "1158b2e41138b6a5c0326359fae6dc7367ce5c018120dd86000000000000000000ffffffffff29ffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffff05000000ffffffffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffff"
    "ffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffffefffffffffff"
    "ffffffffffffffff464ca924936175a3c226a2b45549a1ad253d1a"
  );
  ASSERT_EQ(reproducer.size(), 603u);
  read_refused("vr2b_oom.dcm", reproducer, "refused before parsing");
}

// fuzz_dicom_file, oom-076c2d40…: a 607-byte deflated file with bytes inserted into its meta
// header, after which DCMTK still found a deflate stream (at an offset neither the group
// length nor the elements give) and allocated 3.4 GB. Where DCMTK starts inflating a damaged
// meta header is guesswork, so a deflated file is parsed only after a clean one.
TEST(FuzzRegressions, DeflatedFileWithADamagedMetaHeaderIsRefused) {
  const std::string reproducer = from_hex(
    "000001000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e312e39390200120055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e310002001300000000000000010f29481000545950454d455247455f4354575f31208d90"
    "cd6ed34014854f7e688734a0694155c56a96d960cd386e091b54cb2dd8929309b62b5ac982a062b55db454c18866d557"
    "e892c760c923b0e41158b2e41138b6a5c0326359fae6dc7367ce5c018120dd864da257d1c48ff369128dfde424f78f23"
    "3f16d8c651f404c6719d91a71da3b51e39bb8e713cfe54d9bd43876a1cee9e438f33dc1b69ed0de9768c3bac9df4291c"
    "f8022e4fd0461b018d6cbc065d2f8129d21074cd98a68d2013b8466c1fa35c5c1797c5fcac50a7e5bb2ff38bb2982b81"
    "3b4c27955bcbd84aa48babf2bc282f4ed5a7f2f38705eb2fa8f7ffd3834c42b267eb9ff6767a6ce6faeb56c2be01df5d"
    "ad1fb86b1db755e777e75bf7e6defe9a58ffb9fe55ccee0f7a7f7adf37fe02"
  );
  ASSERT_EQ(reproducer.size(), 607u);
  read_refused("meta_damage_oom.dcm", reproducer, "damaged file meta header");
}

// fuzz_dicom_file, timeout-c20d8cfd…: a 1,208-byte JPEG-compressed slice whose stream has a
// TEM marker (0xFF01) before its frame header. DCMTK's bit-depth scan never moves past TEM
// and looped forever inside chooseRepresentation. Now refused before decoding.
TEST(FuzzRegressions, JpegWithATemMarkerBeforeTheFrameHeaderIsRefused) {
  const std::string reproducer = from_hex(
    "000000000000000000002000000000000000000000000000000000000000000000000000000000000000000000000000"
    "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
    "00000000000000000000000000000000000000000000000000000000000000004449434d02000000554c0400b6000000"
    "020001004f4200000200000000010200020055491a00312e322e3834302e31303030382e352e312e342e312e312e3200"
    "0200030055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000200100055491600"
    "312e322e3834302e31303030382e312e322e342e37300200120055492000312e322e3832362e302e312e333638303034"
    "332e31302e313233342e302e31000200130053481000545950454d455247455f4354575f312008000800435316004f52"
    "4947494e414c5c5052494d4152595c415849414c0800160055491a00312e322e3834302e31303030382e352e312e342e"
    "312e312e32000800180055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e31000800"
    "200044410800323030303031303108003000544d06013030303030300800500053480000080060004353020043540800"
    "70004c4f1400747970656d657267652063745f7772697465722008009000504e0000080030104c4f100053796e746865"
    "7469632073747564792008003e104c4f0c0053796e7468657469632043540800112153545a004c6f73736c657373204a"
    "50454720636f6d7072657373696f6e2c2073656c656374696f6e2076616c756520312c20706f696e74207472616e7366"
    "6f726d20302c20636f6d7072657373696f6e20726174696f20302e333633363410001000504e120053796e7468657469"
    "635e5068616e746f6d20100020004c4f0a0053594e544845544943201000300044410800313930303031303110004000"
    "435302004f201800500044530200312018006000445304003132302018000051435304004846532020000d0055492000"
    "312e322e3832362e302e312e333638303034332e31302e313233342e312e320020000e0055492000312e322e3832362e"
    "302e312e333638303034332e31302e313233342e312e3300200010005348020031202000110049530200312020001200"
    "495302003120200013004953020031202000320044530600305c305c30202000370044530c00315c305c305c305c315c"
    "30202000520055492000312e322e3832362e302e312e333638303034332e31302e313233342e312e3400280002005553"
    "020001002800040043530c004d4f4e4f4348524f4d453220280010005553020004002800110055530200040028003000"
    "44530400315c31202800000155530200100028000101555302000c0028000201555302000b0028000301555302000000"
    "28005210445306002d313032342028005310445302003120e07f10004f420000fffffffffeff00e00400000000000000"
    "feff00e058000000ffd8ffe000104a46494600010100000100010000ff010000000000000101011100ffc40016000101"
    "0100000000000000000000000000080a10ffda0008010100010000cc864322c8190c86459032190c8b206432191fffd9"
    "feffdde000000000"
  );
  ASSERT_EQ(reproducer.size(), 1208u);
  const HeaderReadResult read = read_headers(write_temp("jpeg_tem.dcm", reproducer), {});
  ASSERT_EQ(read.frames.size(), 1u) << read.skip_reason;
  const SliceHeader& frame = read.frames.front();
  std::vector<float> buffer(std::size_t{frame.rows} * frame.columns);
  try {
    read_frames_hu({{&frame, buffer.data()}});
    FAIL() << "decoded a JPEG stream DCMTK cannot scan";
  } catch (const PixelError& error) {
    EXPECT_NE(std::string(error.what()).find("TEM marker"), std::string::npos) << error.what();
  }
}

// The same damage made on purpose: PatientName's 4-byte length (implicit VR) set to 2 GB.
TEST(FuzzRegressions, ElementLongerThanTheFileIsRefused) {
  typemerge::ct_writer::CtSliceSpec spec;
  spec.transfer_syntax = typemerge::ct_writer::TransferSyntax::implicit_little;
  spec.patient_name = "Length^Canary";  // 14 bytes with its padding
  const fs::path file = scratch() / "length.dcm";
  typemerge::ct_writer::write_ct_slice(spec, file);
  std::ifstream in(file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string header("\x10\x00\x10\x00\x0e\x00\x00\x00", 8);
  const std::size_t at = bytes.find(header);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at + 4, 4, std::string("\x00\x00\x00\x80", 4));
  const HeaderReadResult read =
      read_refused("length.dcm", bytes, "(0010,0010) declares 2147483648 bytes");
  EXPECT_EQ(read.kind, FileKind::unreadable);
}

SliceHeader slice_at(double z, std::uint16_t size = 16) {
  SliceHeader h;
  h.kind = FileKind::ct_image;
  h.modality = "CT";
  h.study_uid = "1.1";
  h.series_uid = "1.2";
  h.frame_of_reference_uid = "1.3";
  h.image_type = "ORIGINAL\\PRIMARY\\AXIAL";
  h.path = "/nonexistent/typemerge/z" + std::to_string(z);
  h.sop_instance_uid = "1.4." + std::to_string(z);
  h.rows = size;
  h.columns = size;
  h.bits_allocated = 16;
  h.bits_stored = 12;
  h.high_bit = 11;
  h.photometric = "MONOCHROME2";
  h.orientation = std::array<double, 6>{1, 0, 0, 0, 1, 0};
  h.pixel_spacing = std::array<double, 2>{1, 1};
  h.position = Vec3{0, 0, z};
  return h;
}

// fuzz_series_geometry, crash-121a6ee…: a gap of 3e155 slice steps was converted to long for
// the "N missing slice(s)" message (UBSan: value outside the range of 'long'). Positions are
// any finite DS, so the count is printed from the double.
TEST(FuzzRegressions, AGapOfMoreStepsThanALongHoldsIsReported) {
  const std::vector<SliceHeader> slices = {slice_at(0), slice_at(1), slice_at(2), slice_at(3),
                                           slice_at(3 + 1e20)};
  const StackGeometry g = compute_stack_geometry(slices, {});
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error.find("100000000000000000000 missing slice(s)"), std::string::npos) << g.error;
}

// The same positions with --resample-spacing asked for 1e20 grid slices: the float → int64
// conversion of the slice count was undefined and the count meaningless. Refused now.
TEST(FuzzRegressions, ResamplingToMoreThan2To31SlicesIsRefused) {
  const std::vector<SliceHeader> slices = {slice_at(0), slice_at(1), slice_at(2), slice_at(3),
                                           slice_at(3 + 1e20)};
  GeometryOptions options;
  options.spacing = SpacingPolicy::resample;
  const StackGeometry g = compute_stack_geometry(slices, options);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error.find("more than 2^31 slices"), std::string::npos) << g.error;
}

// Found while fixing the above: a grid of 65535² × 2^30 voxels has 2^64 bytes of floats,
// which wrapped the 64-bit byte count to a few GB and passed the size limit.
TEST(FuzzRegressions, VolumeByteCountDoesNotWrap) {
  const double voxels_per_slice = 65535.0 * 65535.0;
  const double grid_slices = std::ceil(std::ldexp(1.0, 62) / voxels_per_slice);
  const std::vector<SliceHeader> slices = {slice_at(0, 65535), slice_at(1, 65535),
                                           slice_at(grid_slices - 1, 65535)};
  GeometryOptions options;
  options.spacing = SpacingPolicy::resample;
  const auto series = group_into_series(slices, options);
  ASSERT_EQ(series.size(), 1u);
  ASSERT_TRUE(series[0].usable()) << series[0].geometry.error;
  ASSERT_EQ(series[0].geometry.output_slices, static_cast<std::int64_t>(grid_slices));
  LoadOptions load;
  load.max_volume_bytes = std::uint64_t{1} << 40;
  try {
    (void)load_series(series[0], load);
    ADD_FAILURE() << "loaded";
  } catch (const LoadError& error) {
    EXPECT_NE(std::string(error.what()).find("above the limit"), std::string::npos) << error.what();
  }
}

}  // namespace
