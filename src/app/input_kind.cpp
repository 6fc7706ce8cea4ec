#include "app/input_kind.h"

#include "seg/seg_reader.h"

#include <algorithm>
#include <cctype>
#include <string>

namespace typemerge::app {
namespace {

bool ends_with(const std::string& text, std::string_view suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

InputKind input_kind(const std::filesystem::path& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) return InputKind::dicom;
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ends_with(name, ".nii") || ends_with(name, ".nii.gz")) return InputKind::nifti;
  if (ends_with(name, ".nrrd") || ends_with(name, ".nhdr")) return InputKind::nrrd;
  if (seg::is_seg_file(path)) return InputKind::seg;
  return InputKind::dicom;
}

std::string_view to_string(InputKind kind) {
  switch (kind) {
    case InputKind::dicom:
      return "DICOM";
    case InputKind::nifti:
      return "NIfTI";
    case InputKind::nrrd:
      return "NRRD";
    case InputKind::seg:
      return "DICOM SEG";
  }
  return "?";
}

}  // namespace typemerge::app
