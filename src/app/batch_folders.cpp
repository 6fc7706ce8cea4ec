#include "app/batch_folders.h"

#include <xxhash.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using dicom::FileKind;

// What a skipped file is, for counting. Which kinds fail the batch, and why:
//
//   kind                        fails  why
//   unreadable DICOM            yes    DICOM meant to be read, damaged or truncated: data lost
//   CT image that cannot be used yes   a CT slice the loader refuses (attributes missing or
//                                      unsupported): data lost
//   image of another modality   no     not CT by design; --allow-non-ct converts it
//   other image                 no     secondary capture, colour: never a volume
//   DICOM without pixel data    no     DICOMDIR, reports, presentation states beside images
//   not DICOM                   no     notes, spreadsheets, viewers on a CD
//
// `rank` orders a folder's kinds (failures first); `modality` tells modalities apart.
struct Category {
  int rank = 0;
  std::string modality;
  bool operator<(const Category& other) const {
    return std::tie(rank, modality) < std::tie(other.rank, other.modality);
  }
};

enum Rank { kUnreadable, kUnusableCt, kOtherModality, kOtherImage, kNonImage, kNotDicom };

// Modality is a code string (A-Z, 0-9, space, '_', at most 16); anything else a hostile file
// put there is not repeated (""; also for a missing Modality, which the reader gives as "(none)").
std::string shown_modality(const std::string& modality) {
  const bool code_string =
      !modality.empty() && modality.size() <= 16 &&
      std::all_of(modality.begin(), modality.end(), [](char c) {
        return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == ' ' || c == '_';
      });
  return code_string ? modality : "";
}

Category category_of(const dicom::SkippedFile& file) {
  switch (file.kind) {
    case FileKind::unreadable: return {kUnreadable, ""};
    case FileKind::ct_image: return {kUnusableCt, ""};
    case FileKind::other_image:
      if (file.refused_modality.empty()) return {kOtherImage, ""};
      return {kOtherModality, shown_modality(file.refused_modality)};
    case FileKind::non_image: return {kNonImage, ""};
    case FileKind::not_dicom: return {kNotDicom, ""};
  }
  return {kNotDicom, ""};
}

SkippedFiles counted(const Category& category, std::size_t files) {
  const bool one = files == 1;
  SkippedFiles out;
  out.files = files;
  out.counts_as_failure = category.rank == kUnreadable || category.rank == kUnusableCt;
  switch (category.rank) {
    case kUnreadable: out.reason = one ? "unreadable DICOM file" : "unreadable DICOM files"; break;
    case kUnusableCt:
      out.reason = one ? "CT image that cannot be used" : "CT images that cannot be used";
      break;
    case kOtherModality:
      out.reason = category.modality.empty() ? std::string(one ? "image" : "images") +
                                                   " of another modality"
                                             : category.modality + (one ? " image" : " images");
      out.reason += ", not CT (use --allow-non-ct)";
      break;
    case kOtherImage:
      out.reason = one ? "image that is not a CT slice (secondary capture or colour)"
                       : "images that are not CT slices (secondary capture or colour)";
      break;
    case kNonImage:
      out.reason = one ? "DICOM file without pixel data (DICOMDIR, report, ...)"
                       : "DICOM files without pixel data (DICOMDIR, reports, ...)";
      break;
    default: out.reason = one ? "non-DICOM file" : "non-DICOM files"; break;
  }
  return out;
}

}  // namespace

bool FolderWithoutStudy::counts_as_failure() const {
  return std::any_of(skipped.begin(), skipped.end(),
                     [](const SkippedFiles& s) { return s.counts_as_failure; });
}

std::string FolderWithoutStudy::reason() const {
  std::string text;
  for (const SkippedFiles& s : skipped) {
    if (!text.empty()) text += "; ";
    text += std::to_string(s.files) + " " + s.reason;
  }
  return text;
}

std::string folder_id_of(const fs::path& relative_folder) {
  // '/'-separated and "." for the root, so the id does not depend on how the path was built.
  std::string key = relative_folder.lexically_normal().generic_string();
  while (!key.empty() && key.back() == '/') key.pop_back();
  if (key.empty()) key = ".";
  key = "folder:" + key;  // never equal to a study id of the same digits
  char text[17];
  std::snprintf(text, sizeof text, "%012llx",
                static_cast<unsigned long long>(XXH3_64bits(key.data(), key.size()) >> 16));
  return text;
}

std::vector<FolderWithoutStudy> folders_without_study(const dicom::FolderScan& scan,
                                                      const std::vector<StudyPlan>& plans) {
  std::error_code error;
  const bool root_is_folder = fs::is_directory(scan.root, error);
  // Skipped files are relative to the root (the file name alone when the root is a file);
  // study files are as listed, under the root.
  std::set<fs::path> study_folders;
  for (const StudyPlan& plan : plans) {
    for (const fs::path& file : plan.files) {
      study_folders.insert(root_is_folder ? file.lexically_relative(scan.root).parent_path()
                                          : fs::path());
    }
  }
  std::map<fs::path, std::map<Category, std::size_t>> by_folder;
  for (const dicom::SkippedFile& file : scan.skipped) {
    const fs::path folder = file.path.parent_path();
    if (study_folders.count(folder)) continue;
    ++by_folder[folder][category_of(file)];
  }
  std::vector<FolderWithoutStudy> folders;
  for (const auto& [folder, counts] : by_folder) {
    FolderWithoutStudy f;
    f.folder = folder;
    f.folder_id = folder_id_of(folder);
    for (const auto& [category, files] : counts) f.skipped.push_back(counted(category, files));
    folders.push_back(std::move(f));
  }
  std::sort(folders.begin(), folders.end(),
            [](const FolderWithoutStudy& a, const FolderWithoutStudy& b) {
              return a.folder_id < b.folder_id;
            });
  return folders;
}

std::string FolderWithoutStudy::shown_name(bool path) const {
  if (!path) return "folder-" + folder_id;
  return folder.empty() ? std::string(".") : folder.generic_string();
}

StudyOutcome folder_outcome(const FolderWithoutStudy& folder, bool path) {
  StudyOutcome outcome;
  outcome.input = folder.shown_name(path);
  outcome.status = folder.counts_as_failure() ? StudyStatus::no_study : StudyStatus::no_ct;
  outcome.reason = folder.reason();
  outcome.skipped = folder.skipped;
  return outcome;
}

}  // namespace typemerge::app
