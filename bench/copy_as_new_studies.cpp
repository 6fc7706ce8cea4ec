// copy_as_new_studies: copies real DICOM series into a tree of distinct studies for the batch
// measurements (issue 5): `copy_as_new_studies OUT K SRC...` writes OUT/<src name>_<k>/ for
// k = 1..K, each file re-saved by DCMTK with new Study, Series, Frame of Reference and SOP
// Instance UIDs (2.25.<hash>), so every copy is a study of its own. Files DCMTK cannot read are
// skipped. For measurements outside the project only: the copies hold the source's pixels.
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcmetinf.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>

namespace fs = std::filesystem;

namespace {

std::string new_uid(const std::string& old_uid, const std::string& salt) {
  return "2.25." + std::to_string(std::hash<std::string>{}(salt + "|" + old_uid));
}

void rewrite(DcmItem& item, const DcmTagKey& tag, const std::string& salt) {
  OFString value;
  if (item.findAndGetOFString(tag, value).good() && !value.empty()) {
    item.putAndInsertString(tag, new_uid(value.c_str(), salt).c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: copy_as_new_studies OUT K SRC...\n");
    return 2;
  }
  const fs::path out = argv[1];
  const int copies = std::atoi(argv[2]);
  std::size_t written = 0;
  for (int s = 3; s < argc; ++s) {
    const fs::path source = argv[s];
    for (int k = 1; k <= copies; ++k) {
      const std::string salt = source.filename().string() + "#" + std::to_string(k);
      const fs::path target = out / (source.filename().string() + "_" + std::to_string(k));
      for (const auto& entry : fs::recursive_directory_iterator(source)) {
        if (!entry.is_regular_file()) continue;
        DcmFileFormat file;
        if (file.loadFile(entry.path().c_str()).bad()) continue;
        DcmDataset& data = *file.getDataset();
        for (const DcmTagKey& tag : {DCM_StudyInstanceUID, DCM_SeriesInstanceUID,
                                     DCM_FrameOfReferenceUID, DCM_SOPInstanceUID}) {
          rewrite(data, tag, salt);
        }
        rewrite(*file.getMetaInfo(), DCM_MediaStorageSOPInstanceUID, salt);
        const fs::path path = target / entry.path().lexically_relative(source);
        fs::create_directories(path.parent_path());
        if (file.saveFile(path.c_str(), EXS_Unknown).good()) ++written;
      }
    }
  }
  std::printf("%zu files written under %s\n", written, out.c_str());
  return 0;
}
