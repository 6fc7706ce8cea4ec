#include "app/batch_command.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <memory>
#include <optional>
#include <ostream>
#include <thread>

#include "app/batch_files.h"
#include "app/batch_folders.h"
#include "app/batch_manifest.h"
#include "app/batch_summary.h"
#include "app/child_process.h"
#include "app/exit_codes.h"
#include "app/label_mode.h"
#include "app/memory_budget.h"
#include "dicom/patient_identifiers.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::ordered_json;

volatile sig_atomic_t g_interrupted = 0;
extern "C" void on_interrupt(int) { g_interrupted = 1; }

// Ctrl-C, kill and a closed terminal stop the batch cleanly: children killed, work folders
// removed, the summary written. Restores the previous handlers when it goes out of scope.
class InterruptGuard {
 public:
  InterruptGuard() {
    g_interrupted = 0;
    struct sigaction action {};
    action.sa_handler = on_interrupt;
    sigemptyset(&action.sa_mask);
    for (int s = 0; s < 3; ++s) sigaction(kSignals[s], &action, &previous_[s]);
  }
  ~InterruptGuard() {
    for (int s = 0; s < 3; ++s) sigaction(kSignals[s], &previous_[s], nullptr);
  }

 private:
  static constexpr int kSignals[3] = {SIGINT, SIGTERM, SIGHUP};
  struct sigaction previous_[3] {};
};

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The surface options exactly as given, as `--name=value` arguments for `convert`: flags once,
// multi-value options joined with ',' (their delimiter).
std::vector<std::string> given_arguments(const CLI::App& group) {
  std::vector<std::string> arguments;
  for (const CLI::Option* option : group.get_options()) {
    if (option->count() == 0 || option->get_lnames().empty()) continue;
    const std::string name = "--" + option->get_lnames().front();
    if (option->get_expected_min() == 0) {
      arguments.push_back(name);
      continue;
    }
    std::string joined;
    for (const std::string& value : option->results()) joined += (joined.empty() ? "" : ",") + value;
    arguments.push_back(name + "=" + joined);
  }
  return arguments;
}

std::vector<std::string> input_arguments(const InputOptions& input) {
  std::vector<std::string> arguments;
  if (input.resample_spacing) arguments.push_back("--resample-spacing");
  if (input.allow_non_ct) arguments.push_back("--allow-non-ct");
  if (input.follow_symlinks) arguments.push_back("--follow-symlinks");
  arguments.push_back("--max-depth=" + std::to_string(input.max_depth));
  return arguments;
}

// The conversion parameters that decide the outputs (not --threads or --jobs, which do not).
std::string parameter_text(const BatchOptions& options) {
  std::vector<std::string> all = input_arguments(options.input);
  all.insert(all.end(), options.surface_arguments.begin(), options.surface_arguments.end());
  all.insert(all.end(), options.label_arguments.begin(), options.label_arguments.end());
  // Only when not the default, so that manifests of STL batches stay valid.
  if (options.format != "stl") all.push_back("--format=" + options.format);
  // --reduce-to and --max-error changed meaning (quadric decimation → type merging within a
  // bound in mm), and --max-error alone again (the merge → the merge and its locally limited
  // collapses → those collapses moving the kept vertex): outputs made with an older meaning
  // are not up to date.
  auto given = [&](const char* option) {
    return std::any_of(all.begin(), all.end(),
                       [&](const std::string& a) { return a.rfind(option, 0) == 0; });
  };
  if (given("--reduce-to")) {
    all.push_back("--reduction=type-merging");
  } else if (given("--max-error")) {
    all.push_back("--reduction=type-merging,local-collapses,placement");
  }
  std::sort(all.begin(), all.end());
  std::string text;
  for (const std::string& a : all) text += a + "\n";
  return text;
}

struct Shard {
  int k = 1, n = 1;
  bool active() const { return n > 1 || !text.empty(); }
  std::string text;
};

Shard parse_shard(const std::string& text) {
  Shard shard;
  if (text.empty()) return shard;
  int k = 0, n = 0;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &k, &n, &extra) != 2 || n < 1 || k < 1 || k > n) {
    throw CommandError{kExitUsage, "--shard wants K/N with 1 <= K <= N, e.g. 2/8"};
  }
  shard.k = k;
  shard.n = n;
  shard.text = std::to_string(k) + "/" + std::to_string(n);
  return shard;
}

// JSON lines, appended one line per write so that a reader never sees half an event.
class EventLog {
 public:
  EventLog(const std::string& path, Clock::time_point start) : start_(start) {
    if (path.empty()) return;
    file_ = std::fopen(path.c_str(), "a");
    if (file_ == nullptr) throw CommandError{kExitOutputFailed, "cannot open the log " + path};
  }
  ~EventLog() {
    if (file_ != nullptr) std::fclose(file_);
  }
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;

  void write(const std::string& event, ordered_json fields) {
    if (file_ == nullptr) return;
    ordered_json line = {{"t", std::round(seconds_since(start_) * 1000) / 1000}, {"event", event}};
    line.update(fields);
    const std::string text = line.dump() + "\n";
    std::fwrite(text.data(), 1, text.size(), file_);
    std::fflush(file_);
  }

 private:
  Clock::time_point start_;
  std::FILE* file_ = nullptr;
};

// One line per finished study, always; at a terminal also a bar with the time left, estimated
// from the voxels done so far (big series take longer).
class BatchProgress {
 public:
  BatchProgress(std::ostream& log, std::size_t studies, std::uint64_t voxels)
      : log_(log), interactive_(::isatty(STDERR_FILENO) == 1), studies_(studies),
        voxels_(voxels), start_(Clock::now()) {}

  void finished(const std::string& line, std::uint64_t voxels) {
    ++done_;
    voxels_done_ += voxels;
    clear();
    char prefix[32];
    std::snprintf(prefix, sizeof prefix, "[%zu/%zu] ", done_, studies_);
    log_ << prefix << line << "\n" << std::flush;
    drawn_ = false;
  }

  void update(std::size_t running) {
    if (!interactive_ || studies_ == 0) return;
    if (drawn_ && seconds_since(last_draw_) < 0.5) return;
    last_draw_ = Clock::now();
    const double fraction = voxels_ > 0 ? double(voxels_done_) / double(voxels_) : 0;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    std::string bar = "\r[" + std::string(filled, '#') + std::string(kWidth - filled, '.') + "] ";
    char text[128];
    std::snprintf(text, sizeof text, "%zu/%zu studies, %zu running", done_, studies_, running);
    bar += text;
    if (fraction > 0) {
      const double left = seconds_since(start_) * (1 - fraction) / fraction;
      std::snprintf(text, sizeof text, ", about %.0f min %02.0f s left", std::floor(left / 60),
                    std::fmod(left, 60.0));
      bar += text;
    }
    log_ << bar << "\033[K" << std::flush;
    drawn_ = true;
  }

  void clear() {
    if (interactive_ && drawn_) log_ << "\r\033[K" << std::flush;
    drawn_ = false;
  }

 private:
  std::ostream& log_;
  bool interactive_;
  std::size_t studies_;
  std::uint64_t voxels_;
  std::size_t done_ = 0;
  std::uint64_t voxels_done_ = 0;
  Clock::time_point start_;
  Clock::time_point last_draw_{};
  bool drawn_ = false;
};

struct PendingStudy {
  const StudyPlan* plan = nullptr;
  StudyKey key;
  std::optional<StudyRecord> previous;
};

struct RunningStudy {
  PendingStudy study;
  std::unique_ptr<ChildProcess> child;
  Clock::time_point start;
  std::uint64_t estimate = 0;
  fs::path work;
  bool timed_out = false;
};

// 0 every study converted or up to date, 6 none converted, 5 some failed or interrupted or a
// folder's files were lost (no_study: unreadable DICOM, unusable CT images; an interrupted run
// itself exits 130 before this is asked). Folders of files that are not CT by design (no_ct)
// do not count.
int exit_code_of(const BatchTotals& totals) {
  if (totals.converted + totals.up_to_date == 0) return kExitBatchNoneConverted;
  return totals.failed + totals.interrupted + totals.no_study > 0 ? kExitBatchSomeFailed
                                                                  : kExitOk;
}

// ", 1 no_study folder, 2 no_ct folders" for the progress lines; "" when there are none.
std::string folder_counts(const BatchTotals& totals) {
  std::string text;
  for (const auto& [count, status] : {std::pair{totals.no_study, "no_study"},
                                      std::pair{totals.no_ct, "no_ct"}}) {
    if (count == 0) continue;
    text += ", " + std::to_string(count) + " " + status + (count == 1 ? " folder" : " folders");
  }
  return text;
}

StudyOutcome outcome_base(const StudyPlan& plan) {
  StudyOutcome outcome;
  outcome.input = plan.shown_folder;
  outcome.study = plan.study_id;
  outcome.series = plan.series_id;
  outcome.output_name = plan.output_name;
  return outcome;
}

// The reason `convert` gave ("typemerge: <reason>", its last such line).
std::string child_reason(const fs::path& output_file, const ChildResult& result) {
  std::ifstream in(output_file);
  std::string line, reason, last;
  while (std::getline(in, line)) {
    if (line.rfind("typemerge: ", 0) == 0) reason = line.substr(11);
    if (!line.empty()) last = line;
  }
  if (reason.empty()) reason = last;  // e.g. CLI11's messages
  if (!result.exited) {
    const char* name = ::strsignal(result.signal);
    return "the conversion crashed (signal " + std::to_string(result.signal) + ", " +
           (name ? name : "?") + ")";
  }
  if (reason.empty()) reason = "conversion failed with exit code " + std::to_string(result.exit_code);
  return reason;
}

// The surfaces and every warning of convert's report (loading, preprocessing, surfaces).
void read_report(const fs::path& report, const std::string& name, StudyOutcome& outcome) {
  std::ifstream in(report);
  const ordered_json json = ordered_json::parse(in);
  for (const auto& w : json.at("input").at("warnings")) outcome.warnings.push_back(w.get<std::string>());
  if (json.contains("labels")) {
    // Label mode's report (label_mode.h): one entry per label, named by its part's name.
    for (const auto& l : json.at("labels")) {
      outcome.surfaces.push_back({l.at("name").get<std::string>(),
                                  name + "/" + l.at("output").get<std::string>(),
                                  l.at("triangles").get<std::uint64_t>(),
                                  l.at("volume_ml").get<double>(),
                                  l.at("validity").at("closed_manifold").get<bool>(), true});
      for (const auto& w : l.at("warnings")) {
        outcome.warnings.push_back(l.at("name").get<std::string>() + ": " + w.get<std::string>());
      }
    }
    return;
  }
  for (const auto& step : json.at("preprocess")) {
    for (const auto& w : step.at("warnings")) outcome.warnings.push_back(w.get<std::string>());
  }
  for (const auto& s : json.at("surfaces")) {
    const bool met = !s.contains("reduction") || s.at("reduction").is_null() ||
                     s.at("reduction").at("target_met").get<bool>();
    outcome.surfaces.push_back({s.at("name").get<std::string>(),
                                name + "/" + s.at("output").get<std::string>(),
                                s.at("triangles").get<std::uint64_t>(),
                                s.at("volume_ml").get<double>(),
                                s.at("validity").at("closed_manifold").get<bool>(), met});
    for (const auto& w : s.at("warnings")) {
      outcome.warnings.push_back(s.at("name").get<std::string>() + ": " + w.get<std::string>());
    }
  }
}

// Work folders of batches on this host whose process is gone (killed) are removed; those of
// running batches (other shards sharing OUTDIR) are left alone.
void remove_stale_work(const fs::path& work_root, const std::string& host) {
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(work_root, error)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(host + "-", 0) != 0) continue;
    const pid_t pid = static_cast<pid_t>(std::atol(name.c_str() + host.size() + 1));
    if (pid > 0 && ::kill(pid, 0) != 0 && errno == ESRCH) fs::remove_all(entry.path(), error);
  }
}

std::string host_name() {
  char text[256] = {};
  if (::gethostname(text, sizeof text - 1) != 0) return "host";
  return sanitise_component(text);
}

class BatchRun {
 public:
  BatchRun(const BatchOptions& options, std::ostream& log)
      : options_(options), log_(log), out_(options.out), start_(Clock::now()),
        events_(options.log, start_) {}

  int run();

 private:
  void prepare(const std::vector<StudyPlan>& plans);
  void account_for_folders(const dicom::FolderScan& scan, const std::vector<StudyPlan>& plans);
  bool start_study(PendingStudy study, std::uint64_t estimate, const fs::path& my_work,
                   std::vector<RunningStudy>& running);
  void stop_all(std::vector<RunningStudy>& running);
  std::string masked_paths(std::string text, const StudyPlan& plan) const;
  void finish(RunningStudy& running, const ChildResult& result);
  void record(StudyOutcome outcome, std::uint64_t voxels);
  std::vector<std::string> child_arguments(const StudyPlan& plan, const fs::path& work) const;
  // The folder (or file) `convert` is given for the study.
  fs::path study_input(const StudyPlan& plan) const {
    if (plan.source != StudySource::dicom) return root_is_folder_ ? root_ / plan.input_file : root_;
    return root_is_folder_ ? root_ / plan.folder : root_;
  }

  const BatchOptions& options_;
  std::ostream& log_;
  fs::path out_;
  Clock::time_point start_;
  EventLog events_;
  Shard shard_;
  fs::path root_;
  bool root_is_folder_ = true;
  fs::path work_root_;
  std::string parameters_;
  std::uint64_t budget_ = 0;
  ConversionShape shape_;  // what each study's conversion holds besides its grid
  unsigned threads_per_study_ = 1;
  std::deque<PendingStudy> queue_;
  std::vector<StudyOutcome> outcomes_;
  std::unique_ptr<BatchProgress> progress_;
};

// Whether the study is converted in label mode: segmentations always (the batch's --preset,
// --iso and --window do not apply to them), NIfTI and NRRD label maps (batch_plan.h) when
// --labels is given; grey volumes (signed or float samples: CT, MR) never.
bool label_mode_study(const StudyPlan& plan, const BatchOptions& options) {
  switch (plan.source) {
    case StudySource::segmentation_nrrd:
    case StudySource::dicom_seg: return true;
    case StudySource::nifti:
    case StudySource::nrrd:
      return plan.label_map &&
             std::any_of(options.label_arguments.begin(), options.label_arguments.end(),
                         [](const std::string& a) { return a.rfind("--labels=", 0) == 0; });
    default: return false;
  }
}

// The surface options a study's conversion gets: in label mode without the grey ones
// (--preset, --iso, --window) and with the label options; else the grey ones only. Options
// that make no sense for the input (--hollow on a label map, --preset on a label map given
// without --labels) are passed on, and `convert` refuses that study with its reason.
std::vector<std::string> study_surface_arguments(const StudyPlan& plan,
                                                 const BatchOptions& options) {
  if (!label_mode_study(plan, options)) return options.surface_arguments;
  std::vector<std::string> arguments;
  for (const std::string& a : options.surface_arguments) {
    const bool grey = a.rfind("--preset", 0) == 0 || a.rfind("--iso", 0) == 0 ||
                      a.rfind("--window", 0) == 0;
    if (!grey) arguments.push_back(a);
  }
  arguments.insert(arguments.end(), options.label_arguments.begin(), options.label_arguments.end());
  return arguments;
}

std::vector<std::string> BatchRun::child_arguments(const StudyPlan& plan, const fs::path& work) const {
  std::vector<std::string> argv = {current_executable().string()};
  for (std::string& a : study_convert_arguments(study_input(plan), plan, options_, work,
                                                threads_per_study_, budget_)) {
    argv.push_back(std::move(a));
  }
  return argv;
}

void BatchRun::record(StudyOutcome outcome, std::uint64_t voxels) {
  std::string line = outcome.output_name + ": " + status_name(outcome.status);
  if (outcome.status == StudyStatus::converted) {
    char text[64];
    std::snprintf(text, sizeof text, " in %.1f s", outcome.seconds);
    line += text;
  }
  for (const SurfaceOutcome& s : outcome.surfaces) {
    line += ", " + s.surface + " " + std::to_string(s.triangles) + " triangles";
  }
  if (!outcome.reason.empty()) line += ": " + outcome.reason;
  for (const std::string& w : outcome.warnings) line += "\n    warning: " + w;
  progress_->finished(line, voxels);
  ordered_json surfaces = ordered_json::array();
  for (const SurfaceOutcome& s : outcome.surfaces) {
    surfaces.push_back({{"surface", s.surface}, {"file", s.file}, {"triangles", s.triangles}});
  }
  events_.write("study_end", {{"study", outcome.study}, {"output", outcome.output_name},
                              {"status", status_name(outcome.status)}, {"reason", outcome.reason},
                              {"seconds", std::round(outcome.seconds * 1000) / 1000},
                              {"surfaces", surfaces}});
  outcomes_.push_back(std::move(outcome));
}

void BatchRun::prepare(const std::vector<StudyPlan>& plans) {
  for (const StudyPlan& plan : plans) {
    if (!in_shard(plan.study_id, shard_.k, shard_.n)) continue;
    if (!plan.refusal.empty()) {
      StudyOutcome outcome = outcome_base(plan);
      outcome.reason = plan.refusal;
      outcomes_.push_back(outcome);  // reported once the progress exists
      continue;
    }
    PendingStudy study;
    study.plan = &plan;
    study.previous = read_study_record(out_, plan.study_id);
    try {
      study.key = study_key(plan.files, parameters_,
                            study.previous ? study.previous->stamps : std::vector<FileStamp>{});
    } catch (const std::runtime_error&) {
      // Not the path: the summary never names input folders unmasked.
      StudyOutcome outcome = outcome_base(plan);
      outcome.reason = "a file of the study could not be read (removed or unreadable meanwhile)";
      outcomes_.push_back(outcome);
      continue;
    }
    if (study.previous && study.previous->key == study.key.key &&
        study.previous->output_name == plan.output_name && outputs_intact(out_, *study.previous)) {
      try {
        StudyOutcome outcome = outcome_from_json(study.previous->entry_json);
        outcome.status = StudyStatus::up_to_date;
        outcome.input = plan.shown_folder;
        outcome.seconds = outcome.cpu_seconds = outcome.peak_memory_mb = 0;
        outcomes_.push_back(outcome);
        continue;
      } catch (const std::runtime_error&) {
        // an unreadable entry: convert again
      }
    }
    queue_.push_back(std::move(study));
  }
}

// Folders whose files went into no study get entries of their own: a folder of damaged files
// must not vanish from the account of a batch that converted the rest.
void BatchRun::account_for_folders(const dicom::FolderScan& scan,
                                   const std::vector<StudyPlan>& plans) {
  for (const FolderWithoutStudy& folder : folders_without_study(scan, plans)) {
    if (in_shard(folder.folder_id, shard_.k, shard_.n)) {
      outcomes_.push_back(folder_outcome(folder, options_.folder_paths));
    }
  }
}

int BatchRun::run() {
  shard_ = parse_shard(options_.shard);
  budget_ = options_.max_memory.empty() ? default_memory_budget()
                                        : parse_memory_size(options_.max_memory);
  // With --labels alone nothing grey is asked (label mode's estimate: the default shape).
  const bool grey_request = !options_.convert.presets.empty() || !options_.convert.iso.empty() ||
                            !options_.convert.window.empty();
  shape_ = grey_request || options_.convert.labels.empty() ? conversion_shape(options_.convert)
                                                           : ConversionShape{};
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  threads_per_study_ = options_.threads > 0 ? options_.threads
                                            : std::max(1u, cores / std::max(1u, options_.jobs));
  parameters_ = parameter_text(options_);

  std::error_code error;
  fs::create_directories(out_, error);
  if (error || !fs::is_directory(out_)) {
    throw CommandError{kExitOutputFailed, "cannot create the output folder " + out_.string()};
  }
  work_root_ = batch_state_folder(out_) / "work";
  fs::create_directories(work_root_, error);
  if (error) throw CommandError{kExitOutputFailed, "cannot write in " + out_.string()};
  const std::string host = host_name();
  remove_stale_work(work_root_, host);
  const fs::path my_work = work_root_ / (host + "-" + std::to_string(::getpid()));

  const dicom::FolderScan scan = scan_input(options_.input);
  root_ = scan.root;
  root_is_folder_ = fs::is_directory(root_, error);
  for (const std::string& w : scan.warnings) log_ << "warning: " << w << "\n";

  // Patient identifiers are read from one file per study only to keep them out of names.
  std::vector<StudyPlan> plans = plan_studies(scan, options_.filter, options_.name_pattern,
                                              dicom::patient_identifiers);
  // NIfTI, NRRD, SEG and ZIP files among the files the DICOM scan passed over.
  add_file_studies(scan, options_.name_pattern, dicom::patient_identifiers, plans);
  prepare(plans);
  account_for_folders(scan, plans);

  std::uint64_t voxels_to_do = 0;
  for (const PendingStudy& s : queue_) voxels_to_do += s.plan->voxels;
  progress_ = std::make_unique<BatchProgress>(log_, queue_.size(), voxels_to_do);
  const BatchTotals before = totals_of(outcomes_);
  const std::size_t skipped = before.up_to_date, refused = before.failed;
  // ROOT itself is not repeated: archive folder names can spell patient names.
  log_ << "batch: " << plans.size() << (plans.size() == 1 ? " study found" : " studies found")
       << (shard_.active() ? ", shard " + shard_.text : std::string()) << "; " << queue_.size()
       << " to convert, " << skipped << " up to date, " << refused << " without a usable series"
       << folder_counts(before) << "\n"
       << std::flush;
  events_.write("batch_start", {{"studies", plans.size()},
                                {"shard", shard_.text},
                                {"to_convert", queue_.size()},
                                {"up_to_date", skipped},
                                {"refused", refused},
                                {"no_study", before.no_study},
                                {"no_ct", before.no_ct},
                                {"jobs", options_.jobs},
                                {"threads_per_study", threads_per_study_},
                                {"memory_budget_mb", budget_ >> 20}});
  for (const StudyOutcome& o : outcomes_) {
    if (o.status == StudyStatus::no_study || o.status == StudyStatus::no_ct) {
      log_ << o.input << ": " << status_name(o.status) << ": " << o.reason << "\n";
      events_.write("folder", {{"folder", o.input}, {"status", status_name(o.status)},
                               {"reason", o.reason}});
      continue;
    }
    if (o.status == StudyStatus::failed) {
      log_ << o.output_name << ": failed: " << o.reason << "\n";
    }
    events_.write("study_end", {{"study", o.study}, {"output", o.output_name},
                                {"status", status_name(o.status)}, {"reason", o.reason}});
  }

  InterruptGuard guard;
  std::vector<RunningStudy> running;
  std::uint64_t reserved = 0;
  while ((!queue_.empty() || !running.empty()) && !g_interrupted) {
    bool changed = false;
    // Start what the job count and the memory budget allow; one study always runs, even if
    // its estimate alone exceeds the budget (the hard limit then decides).
    while (!queue_.empty() && running.size() < options_.jobs) {
      const StudyPlan& plan = *queue_.front().plan;
      ConversionShape study_shape = shape_;
      study_shape.int16_samples = plan.int16_samples;
      const std::uint64_t estimate = conversion_memory_estimate(
          working_voxels(plan.grid_size, plan.spacing_mm, options_.convert.voxel_size_mm),
          study_shape);
      if (!running.empty() && reserved + estimate > budget_) break;
      PendingStudy next = std::move(queue_.front());
      queue_.pop_front();
      if (start_study(std::move(next), estimate, my_work, running)) reserved += estimate;
      changed = true;
    }
    for (auto it = running.begin(); it != running.end();) {
      if (options_.timeout_seconds > 0 && !it->timed_out &&
          seconds_since(it->start) > options_.timeout_seconds) {
        it->timed_out = true;
        it->child->kill();
      }
      const std::optional<ChildResult> result = it->child->poll();
      if (!result) {
        ++it;
        continue;
      }
      finish(*it, *result);
      reserved -= it->estimate;
      it = running.erase(it);
      changed = true;
    }
    progress_->update(running.size());
    if (!changed) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }

  if (g_interrupted) stop_all(running);
  progress_->clear();
  fs::remove_all(my_work, error);

  const std::string stem =
      shard_.active() ? "summary.shard-" + std::to_string(shard_.k) + "-of-" + std::to_string(shard_.n)
                      : "summary";
  try {
    write_summary(out_, stem, outcomes_, shard_.text);
  } catch (const std::runtime_error& e) {
    throw CommandError{kExitOutputFailed, e.what()};
  }
  const BatchTotals totals = totals_of(outcomes_);
  char line[256];
  std::snprintf(line, sizeof line, "batch: %zu converted, %zu up to date, %zu failed",
                totals.converted, totals.up_to_date, totals.failed);
  log_ << line << folder_counts(totals);
  if (totals.reduce_to_not_met > 0) {
    log_ << ", " << totals.reduce_to_not_met << " surface(s) short of --reduce-to";
  }
  std::snprintf(line, sizeof line, "%s in %.1f s; summary in ",
                g_interrupted ? ", interrupted" : "", seconds_since(start_));
  log_ << line << (out_ / (stem + ".json")).string() << "\n";
  const int code = g_interrupted ? kExitInterrupted : exit_code_of(totals);
  events_.write("batch_end", {{"converted", totals.converted}, {"up_to_date", totals.up_to_date},
                              {"failed", totals.failed}, {"no_study", totals.no_study},
                              {"no_ct", totals.no_ct}, {"interrupted", bool(g_interrupted)},
                              {"seconds", std::round(seconds_since(start_) * 1000) / 1000},
                              {"exit_code", code}});
  return code;
}

// Starts the study's conversion in a child process; false (and the study recorded as failed)
// when no process could be started.
bool BatchRun::start_study(PendingStudy study, std::uint64_t estimate, const fs::path& my_work,
                           std::vector<RunningStudy>& running) {
  RunningStudy r;
  r.study = std::move(study);
  r.estimate = estimate;
  r.work = my_work / r.study.plan->study_id;
  std::error_code error;
  fs::remove_all(r.work, error);
  fs::create_directories(r.work / "out", error);
  if (error) throw CommandError{kExitOutputFailed, "cannot write in " + r.work.string()};
  // The child limits itself (--max-memory): it refuses a series whose estimate exceeds the
  // budget before loading it, and its address space is bounded.
  ChildSpec spec{child_arguments(*r.study.plan, r.work), r.work / "output.txt"};
  r.start = Clock::now();
  try {
    r.child = std::make_unique<ChildProcess>(spec);
  } catch (const std::runtime_error& e) {
    StudyOutcome outcome = outcome_base(*r.study.plan);
    outcome.reason = e.what();
    record(std::move(outcome), r.study.plan->voxels);
    return false;
  }
  events_.write("study_start", {{"study", r.study.plan->study_id},
                                {"output", r.study.plan->output_name},
                                {"series", r.study.plan->series_id},
                                {"memory_estimate_mb", estimate >> 20}});
  running.push_back(std::move(r));
  return true;
}

// convert's messages may name the folder it was given; the summary shows it masked (folder
// names can spell patient names) and relative to ROOT.
std::string BatchRun::masked_paths(std::string text, const StudyPlan& plan) const {
  const std::string input = study_input(plan).string();
  for (std::size_t at = text.find(input); at != std::string::npos;
       at = text.find(input, at + plan.shown_folder.size())) {
    text.replace(at, input.size(), plan.shown_folder);
  }
  return text;
}

// Ctrl-C, SIGTERM, SIGHUP: the running children are killed (their work folders go with the
// batch's), and they and the queued studies are recorded as interrupted.
void BatchRun::stop_all(std::vector<RunningStudy>& running) {
  auto interrupted = [this](const StudyPlan& plan) {
    StudyOutcome outcome = outcome_base(plan);
    outcome.status = StudyStatus::interrupted;
    outcome.reason = "interrupted";
    outcomes_.push_back(std::move(outcome));
  };
  for (RunningStudy& r : running) {
    r.child->kill();
    while (!r.child->poll()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    interrupted(*r.study.plan);
  }
  running.clear();
  for (const PendingStudy& s : queue_) interrupted(*s.plan);
  queue_.clear();
}

void BatchRun::finish(RunningStudy& r, const ChildResult& result) {
  const StudyPlan& plan = *r.study.plan;
  StudyOutcome outcome = outcome_base(plan);
  outcome.seconds = seconds_since(r.start);
  outcome.cpu_seconds = result.cpu_seconds;
  outcome.peak_memory_mb = double(result.peak_rss_bytes) / (1 << 20);
  std::error_code error;
  if (r.timed_out) {
    char text[96];
    std::snprintf(text, sizeof text, "time limit of %g s exceeded (--timeout)",
                  options_.timeout_seconds);
    outcome.reason = text;
  } else if (!result.exited || result.exit_code != 0) {
    outcome.reason = masked_paths(child_reason(r.work / "output.txt", result), plan);
    if (outcome.reason == "out of memory") {
      outcome.reason += " (limit " + format_megabytes(budget_) + ", --max-memory)";
    }
  } else {
    try {
      read_report(r.work / "report.json", plan.output_name, outcome);
      for (std::string& w : outcome.warnings) w = masked_paths(std::move(w), plan);
      // Outputs move into place file by file (rename: atomic), then the record is written: a
      // batch killed in between has no record and converts the study again.
      const fs::path destination = out_ / plan.output_name;
      fs::create_directories(destination);
      StudyRecord record;
      record.study_id = plan.study_id;
      record.key = r.study.key.key;
      record.output_name = plan.output_name;
      record.stamps = r.study.key.stamps;
      std::vector<fs::path> produced;
      for (const auto& entry : fs::directory_iterator(r.work / "out")) {
        const std::string name = entry.path().filename().string();
        if (!entry.is_regular_file() || name.front() == '.') continue;  // no temporaries
        produced.push_back(entry.path());
      }
      std::sort(produced.begin(), produced.end());
      for (const fs::path& file : produced) {
        const fs::path target = destination / file.filename();
        fs::rename(file, target);
        record.outputs.push_back({plan.output_name + "/" + file.filename().string(),
                                  static_cast<std::uint64_t>(fs::file_size(target))});
      }
      // Outputs of an earlier run that this one did not make again (other presets, say).
      if (r.study.previous) {
        for (const OutputFile& old : r.study.previous->outputs) {
          if (std::none_of(record.outputs.begin(), record.outputs.end(),
                           [&](const OutputFile& now) { return now.path == old.path; })) {
            fs::remove(out_ / old.path, error);
          }
        }
      }
      outcome.status = StudyStatus::converted;
      record.entry_json = outcome_json(outcome);
      write_study_record(out_, record);
    } catch (const std::exception& e) {
      outcome.status = StudyStatus::failed;
      outcome.surfaces.clear();
      outcome.warnings.clear();
      outcome.reason = std::string("could not collect the outputs: ") + e.what();
    }
  }
  fs::remove_all(r.work, error);
  record(std::move(outcome), plan.voxels);
}

}  // namespace

std::vector<std::string> study_convert_arguments(const fs::path& input, const StudyPlan& plan,
                                                 const BatchOptions& options,
                                                 const fs::path& work, unsigned threads,
                                                 std::uint64_t budget) {
  std::vector<std::string> argv = {"convert", input.string()};
  if (plan.source == StudySource::dicom) {
    argv.push_back("--series");
    argv.push_back(plan.series_id);
  }
  for (const std::string& a : input_arguments(options.input)) argv.push_back(a);
  for (const std::string& a : study_surface_arguments(plan, options)) argv.push_back(a);
  // With --format 3mf one package, named like the study's output folder (so that packages
  // gathered from several studies do not collide); else a folder of STL files.
  const std::string package = fs::path(plan.output_name).filename().string() + ".3mf";
  const fs::path output = options.format == "3mf" ? work / "out" / package : work / "out";
  // The report gives the summary its surfaces and warnings; its sampled distances to marching
  // cubes' surface are left out (the summary has none, and measuring them took longer than the
  // conversion: 3.5 s against 0.4 s for the abdomen's bone, docs/benchmarks.md).
  for (const std::string& a :
       {std::string("-o"), output.string(), std::string("--report"),
        (work / "report.json").string(), std::string("--report-without-distances"),
        std::string("--threads"), std::to_string(threads),
        "--max-memory=" + std::to_string(budget)}) {
    argv.push_back(a);
  }
  return argv;
}

void add_batch_command(CLI::App& app, BatchOptions& options) {
  CLI::App* command = app.add_subcommand(
      "batch", "Convert every study under a folder tree (resumable, parallel, shardable)");
  add_input_options(*command, options.input, /*required=*/false);
  command->add_option("--out", options.out, "Output folder (outputs, summary, manifest)")
      ->required();
  command->add_option("--format", options.format,
                      "stl: an STL file per surface (default); 3mf: one 3MF package per study "
                      "holding every surface as a named, coloured object")
      ->check(CLI::IsMember({"stl", "3mf"}));
  command->add_option("--name", options.name_pattern,
                      "Output folder of a study under --out: a pattern of {folder} (the study's "
                      "folder under ROOT), {study} and {series} (hashed ids); default {folder}");
  command->add_option("--series-description", options.filter.description_regex,
                      "Only series whose description matches this regular expression");
  command->add_option("--kernel", options.filter.kernel_regex,
                      "Only series whose convolution kernel matches this regular expression");
  command->add_option("--min-thickness", options.filter.min_thickness_mm,
                      "Only series with slices at least this thick (mm)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--max-thickness", options.filter.max_thickness_mm,
                      "Only series with slices at most this thick (mm)")
      ->check(CLI::PositiveNumber);
  command->add_option("-j,--jobs", options.jobs, "Studies converted at once (default 1)")
      ->check(CLI::Range(1u, 256u));
  command->add_option("--threads", options.threads,
                      "Threads per study (default: cores / jobs); outputs do not depend on it")
      ->check(CLI::Range(0u, 256u));
  command->add_option("--max-memory", options.max_memory,
                      "Memory budget of the batch, e.g. 8G (default: 3/4 of the physical "
                      "memory); studies start only while their estimates fit, and each study "
                      "is also limited to it");
  command->add_option("--timeout", options.timeout_seconds,
                      "Seconds a study may take before it is stopped and recorded as failed "
                      "(default 3600; 0: no limit)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--log", options.log, "Append a JSON-lines event log to this file");
  command->add_option("--shard", options.shard,
                      "K/N: convert only the K-th of N deterministic shares of the studies (one "
                      "job of a Slurm array, GNU parallel, ...); writes summary.shard-K-of-N.*");
  command->add_flag("--merge-summaries", options.merge_summaries,
                    "Join the shard summaries in --out into summary.json and summary.csv");
  command->add_flag("--folder-paths", options.folder_paths,
                    "Name folders without a study by their path under ROOT instead of "
                    "folder-<id> (paths may hold patient names)");
  CLI::App* surface = command->add_option_group("Surface");
  add_surface_options(*surface, options.convert);
  // In their own group: a tree may hold CT series (--preset) and label maps (--labels) at once.
  CLI::App* labels = command->add_option_group("Labels");
  CLI::App unused_surface;
  add_label_options(*labels, unused_surface, options.convert);
  command->callback([&options, surface, labels] {
    options.surface_arguments = given_arguments(*surface);
    options.label_arguments = given_arguments(*labels);
  });
}

int run_batch(const BatchOptions& options, std::ostream& log) {
  if (options.merge_summaries) {
    try {
      const auto outcomes = merge_shard_summaries(options.out);
      const BatchTotals totals = totals_of(outcomes);
      log << "batch: joined " << totals.studies() << " studies"
          << folder_counts(totals) << " into "
          << (fs::path(options.out) / "summary.json").string() << "\n";
      return exit_code_of(totals);
    } catch (const std::runtime_error& error) {
      throw CommandError{kExitInputRefused, error.what()};
    }
  }
  if (options.input.input.empty()) {
    throw CommandError{kExitUsage, "batch needs the folder to convert (ROOT)"};
  }
  // Unknown presets and empty requests are refused up front; with --labels alone the DICOM
  // studies of the tree (if any) are refused one by one, as nothing was asked of them.
  const bool grey_request = !options.convert.presets.empty() || !options.convert.iso.empty() ||
                            !options.convert.window.empty();
  if (grey_request || options.convert.labels.empty()) {
    try {
      surface_specs(options.convert);
    } catch (const CommandError& error) {
      if (grey_request) throw;
      throw CommandError{error.exit_code,
                         error.message + ", or --labels all|N[,N...] for label maps"};
    }
  }
  try {
    dicom::SeriesInfo probe;
    options.filter.accepts(probe);  // malformed regular expressions are refused up front
    if (!options.max_memory.empty()) parse_memory_size(options.max_memory);
  } catch (const std::invalid_argument& error) {
    throw CommandError{kExitUsage, error.what()};
  }
  BatchRun run(options, log);
  try {
    return run.run();
  } catch (const CommandError& error) {
    if (error.exit_code == kExitInputRefused) {
      throw CommandError{kExitUsage, error.message};  // ROOT missing or unreadable
    }
    throw;
  }
}

}  // namespace typemerge::app
