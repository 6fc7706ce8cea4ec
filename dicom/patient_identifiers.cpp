#include "dicom/patient_identifiers.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>

namespace typemerge::dicom {
namespace {

constexpr Uint32 kLazyValueBytes = 4096;  // pixel data stays on disk

void add_value(DcmDataset& dataset, const DcmTagKey& tag, std::vector<std::string>& values) {
  OFString text;
  for (unsigned long i = 0; dataset.findAndGetOFString(tag, text, i).good(); ++i) {
    std::string value = text.c_str();
    if (!value.empty()) values.push_back(value);
  }
}

}  // namespace

std::vector<std::string> patient_identifiers(const std::filesystem::path& file) {
  DcmFileFormat format;
  if (format.loadFile(OFFilename(file.c_str()), EXS_Unknown, EGL_noChange, kLazyValueBytes,
                      ERM_autoDetect)
          .bad()) {
    return {};
  }
  DcmDataset& dataset = *format.getDataset();
  std::vector<std::string> values;
  OFString name;
  if (dataset.findAndGetOFStringArray(DCM_PatientName, name).good() && !name.empty()) {
    const std::string whole = name.c_str();
    values.push_back(whole);
    // Family^Given^Middle^Prefix^Suffix, with '=' between alphabetic, ideographic, phonetic.
    std::string part;
    for (char c : whole + "^") {
      if (c == '^' || c == '=' || c == ' ') {
        if (!part.empty()) values.push_back(part);
        part.clear();
      } else {
        part += c;
      }
    }
  }
  for (const DcmTagKey& tag : {DCM_PatientID, DCM_RETIRED_OtherPatientIDs, DCM_IssuerOfPatientID,
                               DCM_AccessionNumber, DCM_PatientBirthDate, DCM_StudyID,
                               DCM_OtherPatientNames}) {
    add_value(dataset, tag, values);
  }
  return values;
}

}  // namespace typemerge::dicom
