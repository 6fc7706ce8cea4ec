// folders_without_study: the input folders a batch would otherwise pass over in silence.
//
// A folder under ROOT that directly holds files, none of which went into a study (every file
// skipped by the scan: damaged, not DICOM, not CT), gets an entry of its own in the summary,
// with its files counted by kind. Such a folder has no DICOM attributes its name could be
// compared with (see batch_plan.h), so it is shown by a stable hash of its path, "folder-<id>",
// and by the path itself only when the user asks (--folder-paths). Shards take folders by that
// id, as they take studies by theirs.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "app/batch_plan.h"
#include "app/batch_summary.h"
#include "dicom/series_scan.h"

namespace typemerge::app {

struct FolderWithoutStudy {
  std::string folder_id;               // 12 hex digits of a hash of `folder`
  std::filesystem::path folder;        // relative to the root ("" for the root); never shown
  std::vector<SkippedFiles> skipped;   // one entry per kind of file: failures first

  // The folder fails the batch (status no_study) when one of its kinds does: unreadable
  // DICOM or CT images that cannot be used. Otherwise (status no_ct) it held only files that
  // are not CT by design: not DICOM, non-image DICOM such as a DICOMDIR, other modalities.
  bool counts_as_failure() const;
  // "folder-<id>", or with `path` the folder under ROOT ("." for ROOT itself).
  std::string shown_name(bool path = false) const;
  // `skipped` as one line: "3 unreadable DICOM files; 2 non-DICOM files".
  std::string reason() const;
};

// Every folder of `scan` holding skipped files and no file of any of `plans` (whatever became
// of those studies: a failed study has an entry of its own), sorted by id.
std::vector<FolderWithoutStudy> folders_without_study(const dicom::FolderScan& scan,
                                                      const std::vector<StudyPlan>& plans);

// The id of a folder given relative to the root (stable across runs, shards and machines
// for the same tree; "" and "." are the root).
std::string folder_id_of(const std::filesystem::path& relative_folder);

// The folder's summary entry: status no_study or no_ct, the masked name (or with `path` the
// folder's path under ROOT) as input, no study.
StudyOutcome folder_outcome(const FolderWithoutStudy& folder, bool path = false);

}  // namespace typemerge::app
