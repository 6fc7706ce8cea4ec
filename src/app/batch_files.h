// add_file_studies: the files of a study tree that are studies by themselves.
//
// A NIfTI (.nii, .nii.gz), a NRRD (.nrrd, .nhdr with its data file; 3D Slicer's .seg.nrrd), a
// DICOM Segmentation and a ZIP archive of DICOM are each one study. The DICOM scan passes over
// them (not DICOM, or DICOM without CT images) and lists them among its skipped files; they are
// found there, so the tree is walked once. A SEG lying beside (or inside the folder of) its CT
// series is a study of its own, converted in label mode, while the series is converted as any
// DICOM study.
//
// Each file study gets:
//   - a study id: 12 hex digits of a hash of "file:" and its path under the root (stable across
//     runs, shards and machines for the same tree; never equal to a DICOM study's id);
//   - its files: the file (and a .nhdr's data file), whose contents key the manifest;
//   - its grid from the header alone (NIfTI, NRRD, SEG; none for a ZIP) for the memory
//     estimate; a header that cannot be read makes the study refused with the reader's
//     reason (which never names the file);
//   - series id: what it is, "nifti", "nrrd", "seg.nrrd", "seg" or "zip".
//
// Names. {folder} is the file's path under the root without its extension (".nii.gz",
// ".seg.nrrd", ...), shown masked: a component spelling a patient identifier becomes
// "study-<id>" (the last one "<kind>-<id>"), as for DICOM studies; the values compared are the
// SEG's own patient attributes and those of every DICOM study whose folder contains the file or
// lies under its folder (a NIfTI or NRRD has none of its own). Because tools name such files
// after acquisition dates, times and numbers (dcm2niix: protocol, "%t" time, "%i" ID), every
// run of at least 6 digits — joined by single '-', '_', '.' or ':' to groups of two or more, as
// in 2021-03-14 or 10:42:05 — is replaced by "N" in every component, whatever the identifiers. What remains
// (a protocol, an organ, "label") is shown. A name that collides (case-insensitively) with a
// DICOM study's or another file study's gets its study id appended; DICOM studies keep theirs.
#pragma once

#include <string>
#include <vector>

#include "app/batch_plan.h"
#include "dicom/series_scan.h"

namespace typemerge::app {

// Appends the file studies of `scan` to `plans` (the DICOM studies plan_studies made of it) and
// sorts all by output name, then id. A scan of a single file (ROOT is the file) gives that file
// as the one study, if it is one.
void add_file_studies(const dicom::FolderScan& scan, const std::string& name_pattern,
                      const IdentifyingValues& identifying, std::vector<StudyPlan>& plans);

// `component` with every run of ≥ 6 digits (see above) replaced by "N".
std::string without_digit_runs(const std::string& component);

// The kind of a file by its name and first bytes, or nullopt when it is not a file study
// (a CT slice, a DICOM file of another kind, a text file). `file` exists.
std::optional<StudySource> file_study_source(const std::filesystem::path& file);

// "nifti", "nrrd", "seg.nrrd", "seg", "zip"; "dicom" for a DICOM study.
const char* source_name(StudySource source);

}  // namespace typemerge::app
