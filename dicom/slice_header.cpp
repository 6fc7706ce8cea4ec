#include "dicom/slice_header.h"

namespace typemerge::dicom {

const char* to_string(FileKind kind) {
  switch (kind) {
    case FileKind::ct_image: return "CT image";
    case FileKind::other_image: return "other image";
    case FileKind::non_image: return "non-image DICOM";
    case FileKind::not_dicom: return "not DICOM";
    case FileKind::unreadable: return "unreadable DICOM";
  }
  return "?";
}

bool SliceHeader::is_localizer() const {
  return image_type.find("LOCALIZER") != std::string::npos;
}

}  // namespace typemerge::dicom
