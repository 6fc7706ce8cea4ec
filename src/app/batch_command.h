// `typemerge batch ROOT --preset bone[,skin…] --out OUTDIR [--format stl|3mf]`: every study
// under ROOT converted with the options of `convert` (an STL per surface, or one 3MF package),
// each in a child process of its own (a crash, a hang or a memory limit ends that study only),
// several at once within a memory budget, resumable (a manifest keyed by input content, tool
// version and parameters), shardable across the jobs of a cluster scheduler, with a summary and
// an optional JSON-lines event log.
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "app/batch_plan.h"
#include "app/convert_command.h"

namespace typemerge::app {

struct BatchOptions {
  InputOptions input;      // ROOT and how it is searched
  ConvertOptions convert;  // the surface options, checked here and passed on to `convert`
  std::vector<std::string> surface_arguments;  // those options as given, to pass on
  // --labels, --label-names, --label-smoothing as given: passed on to the studies converted
  // in label mode (segmentations always; NIfTI and NRRD files when --labels is given).
  std::vector<std::string> label_arguments;
  std::string out;
  std::string format = "stl";  // stl: an STL per surface; 3mf: one package per study
  std::string name_pattern = kDefaultNamePattern;
  SeriesFilter filter;
  unsigned jobs = 1;
  unsigned threads = 0;      // per study; 0: cores / jobs
  std::string max_memory;    // e.g. "8G"; default three quarters of the physical memory
  double timeout_seconds = 3600;  // per study; 0: none
  std::string log;           // JSON lines, appended
  std::string shard;         // "K/N"
  bool merge_summaries = false;
  // Folders without a study named by their path under ROOT, not by folder-<id> (a path may
  // hold a patient's name: only when the user asks).
  bool folder_paths = false;
};

// Exit codes of `batch` (README "Exit codes"): 0 every study converted or up to date,
// 5 some failed or a folder's DICOM files could not be used (no_study), 6 none converted,
// 2 bad arguments, 3 output folder unusable, 130 interrupted.
inline constexpr int kExitBatchSomeFailed = 5;
inline constexpr int kExitBatchNoneConverted = 6;
inline constexpr int kExitInterrupted = 130;

void add_batch_command(CLI::App& app, BatchOptions& options);

// The arguments (after the executable) of the `convert` child that converts one study from
// `input` into `work`/out with a report in `work`/report.json (without the sampled distances
// to marching cubes' surface, which the summary does not use), on `threads` threads and
// within `budget` bytes.
std::vector<std::string> study_convert_arguments(const std::filesystem::path& input,
                                                 const StudyPlan& plan,
                                                 const BatchOptions& options,
                                                 const std::filesystem::path& work,
                                                 unsigned threads, std::uint64_t budget);
int run_batch(const BatchOptions& options, std::ostream& log);

}  // namespace typemerge::app
