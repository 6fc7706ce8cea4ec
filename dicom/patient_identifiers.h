// patient_identifiers: the values of one file that name or identify the patient, read only to
// keep them OUT of what the tool writes (batch output names built from folder names). They are
// never stored, printed or returned to anything that writes.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace typemerge::dicom {

// PatientName (each component and the whole), PatientID, OtherPatientIDs and -Names,
// IssuerOfPatientID,
// AccessionNumber, PatientBirthDate, StudyID. Empty when the file cannot be read; call it only
// on files the header reader accepted (it has run the nesting pre-scan on them).
std::vector<std::string> patient_identifiers(const std::filesystem::path& file);

}  // namespace typemerge::dicom
