// input_kind: what an input path is, decided by the path (a folder, or a file's name) before
// anything is read — except a DICOM Segmentation, which no name marks: its SOP class decides. Every command that takes an input dispatches on it; a new kind of
// input is a new enumerator here and a case where the commands switch on it.
#pragma once

#include <filesystem>
#include <string_view>

namespace typemerge::app {

enum class InputKind {
  dicom,  // a folder of DICOM files (searched recursively), or one DICOM file
  nifti,  // .nii, .nii.gz
  nrrd,   // .nrrd (including 3D Slicer's .seg.nrrd), .nhdr with its data file
  seg,    // a DICOM Segmentation file (seg/seg_reader.h), whatever its name
};

// Folders are DICOM; files by their name's ending (case-insensitive); any other file a SEG
// when its SOP class says so (seg::is_seg_file), else DICOM.
InputKind input_kind(const std::filesystem::path& path);

std::string_view to_string(InputKind kind);  // "DICOM", "NIfTI", "NRRD", "DICOM SEG"

}  // namespace typemerge::app
