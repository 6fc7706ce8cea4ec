// The batch summary: OUTDIR/summary.json and summary.csv (or summary.shard-K-of-N.* for one
// shard), one entry per study and one per input folder no study came from (see
// batch_folders.h), and the step that joins the shards' summaries into one.
// Entries carry no patient data: the input folder is shown masked (see batch_plan.h), series and
// studies by their hashed ids, folders without a study by theirs.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace typemerge::app {

struct SurfaceOutcome {
  std::string surface;  // preset name, "iso" or "window"
  std::string file;     // relative to OUTDIR
  std::uint64_t triangles = 0;
  double volume_ml = 0;
  bool closed_manifold = false;
  bool reduce_to_met = true;  // false: convert's --reduce-to count was not reached
};

// no_study and no_ct are folders, not studies: files no study came of; no_study counts as a
// failure (unreadable DICOM, unusable CT images), no_ct does not (only files that are not CT
// by design: not DICOM, DICOMDIR and other non-image DICOM, images of other modalities).
enum class StudyStatus { converted, up_to_date, failed, interrupted, no_study, no_ct };
const char* status_name(StudyStatus status);

// Files of one kind that a folder held and that went into no study.
struct SkippedFiles {
  std::size_t files = 0;
  std::string reason;  // e.g. "unreadable DICOM files" (agrees with `files` in number)
  bool counts_as_failure = false;
};

struct StudyOutcome {
  std::string input;        // masked relative input folder, or "folder-<id>" (no_study, no_ct)
  std::string study;        // study id (empty for a folder)
  std::string series;       // chosen series id (may be empty)
  std::string output_name;  // folder under OUTDIR
  StudyStatus status = StudyStatus::failed;
  std::string reason;       // why it failed; for a folder its `skipped` as one line
  std::vector<SkippedFiles> skipped;  // a folder's files by kind
  std::vector<SurfaceOutcome> surfaces;
  std::vector<std::string> warnings;  // convert's (loading, preprocessing, surfaces)
  double seconds = 0;       // wall time of the conversion (0 when not run now)
  double cpu_seconds = 0;
  double peak_memory_mb = 0;
};

std::string outcome_json(const StudyOutcome& outcome);  // one JSON object
StudyOutcome outcome_from_json(const std::string& json);  // throws std::runtime_error

struct BatchTotals {
  std::size_t converted = 0, up_to_date = 0, failed = 0, interrupted = 0;
  std::size_t no_study = 0, no_ct = 0;  // folders
  std::size_t reduce_to_not_met = 0;    // surfaces of converted or up-to-date studies
  std::size_t studies() const { return converted + up_to_date + failed + interrupted; }
};
BatchTotals totals_of(const std::vector<StudyOutcome>& outcomes);

// Writes `<stem>.json` and `<stem>.csv` in `out_root` atomically; studies sorted by output
// name, then folders by id. `shard` is "" or "K/N". Throws std::runtime_error when they
// cannot be written.
void write_summary(const std::filesystem::path& out_root, const std::string& stem,
                   std::vector<StudyOutcome> outcomes, const std::string& shard);

// Reads every summary.shard-K-of-N.json in `out_root`, checks that shards 1..N are all there
// and agree on N, and writes summary.json/.csv of their union. Returns the joined outcomes.
// Throws std::runtime_error naming what is missing or inconsistent.
std::vector<StudyOutcome> merge_shard_summaries(const std::filesystem::path& out_root);

}  // namespace typemerge::app
