// The cluster recipes run as written (docs/cluster.md, linked from README "Clusters"): its GNU
// parallel lines, and scripts/slurm/submit.sh and typemerge-array.sbatch on a real single-node
// Slurm that this test starts and stops itself. The lines are read from docs/cluster.md and run
// with only the paths (/archive/export, /data/meshes, scripts/) and the shard count replaced;
// typemerge is found on PATH, as a user's would be.
//
// Slurm: munged, slurmctld and slurmd run as root in the foreground, children of this process
// (PR_SET_PDEATHSIG: they die with it, even if ctest kills it), with their key, sockets,
// state, spool and logs in a temporary folder, on free ports, reached through SLURM_CONF. They
// are stopped by their pids when the suite ends, pass or fail. Without Slurm or root the tests
// skip saying why, except under CI=true, where they fail. Every wait has a deadline, so a
// Slurm that hangs fails the test instead of hanging it.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>

#include "app/batch_outputs.h"
#include "app/batch_plan.h"
#include "app/study_tree.h"
#include "support/scratch_files.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using typemerge::test::comparable;
using typemerge::test::fresh_dir;
using typemerge::test::read_file_bytes;
using typemerge::test::summary_of;
using Clock = std::chrono::steady_clock;

constexpr int kShards = 3;  // the README's 16 would be 16 tasks for the same 6 studies
constexpr auto kJobDeadline = std::chrono::seconds(120);

bool under_ci() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

struct Shell {
  int exit_code = -1;
  std::string out;  // stdout and stderr together
};

Shell shell(const std::string& command) {
  Shell result;
  FILE* pipe = ::popen(("(" + command + ") 2>&1").c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer{};
  while (std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    result.out.append(buffer.data(), n);
  }
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::optional<fs::path> find_program(const std::string& name) {
  std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
  path += ":/usr/sbin:/sbin:/usr/bin:/bin";
  std::stringstream dirs(path);
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const fs::path candidate = fs::path(dir) / name;
    if (!dir.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return std::nullopt;
}

bool wait_until(const std::function<bool()>& done, std::chrono::seconds deadline) {
  const auto end = Clock::now() + deadline;
  while (!done()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

// The typemerge executable's folder first on PATH: the README's lines say `typemerge`.
std::string with_typemerge_on_path() {
  return "PATH=" + fs::path(TYPEMERGE_EXE).parent_path().string() + ":$PATH";
}

// The line of docs/cluster.md that starts with `prefix`, with the example paths replaced.
std::string readme_line(const std::string& prefix, const fs::path& root, const fs::path& out) {
  std::istringstream readme(
      read_file_bytes(fs::path(TYPEMERGE_SOURCE_DIR) / "docs" / "cluster.md"));
  for (std::string line; std::getline(readme, line);) {
    if (line.rfind(prefix, 0) != 0) continue;
    for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
             {"/archive/export", root.string()},
             {"/data/meshes", out.string()},
             {"scripts/", std::string(TYPEMERGE_SOURCE_DIR) + "/scripts/"},
             {"TYPEMERGE_SHARDS=16", "TYPEMERGE_SHARDS=" + std::to_string(kShards)}}) {
      for (std::size_t at = line.find(from); at != std::string::npos;
           at = line.find(from, at + to.size())) {
        line.replace(at, from.size(), to);
      }
    }
    return line;
  }
  ADD_FAILURE() << "docs/cluster.md has no line starting with: " << prefix;
  return "false";
}

// The study tree of the batch tests (three studies convert, one fails in convert, one is
// refused for a missing slice, two folders hold no CT) and study F, big enough (about a
// second) that a task can be cancelled while converting it.
const fs::path& tree() {
  static const fs::path root = [] {
    const fs::path dir = fresh_dir("cluster_tree");
    typemerge::test::write_study_tree(dir);
    typemerge::ct_writer::SeriesLayout layout;
    layout.uid_seed = "cluster_test/F";
    layout.columns = layout.rows = 256;
    layout.slices = 160;
    // A ball of gyroid sponge: a large surface (many triangles) from a small series.
    layout.hu = [](int i, int j, int k) {
      const double w = 2 * 3.14159265358979 / 24;
      const double gyroid = std::sin(i * w) * std::cos(j * w) + std::sin(j * w) * std::cos(k * w) +
                            std::sin(k * w) * std::cos(i * w);
      return std::hypot(i - 127.5, j - 127.5, k - 79.5) < 75 && gyroid > 0 ? 1000.0 : -1000.0;
    };
    typemerge::ct_writer::write_series(typemerge::ct_writer::make_axial_series(layout),
                                       dir / "siteF" / "studyF" / "s1");
    return dir;
  }();
  return root;
}
const char* const kBigStudy = "siteF/studyF/s1";

// Outputs as the batch tests compare them, less the Slurm jobs' logs (typemerge-merge-%j.out).
std::map<std::string, std::string> outputs_of(const fs::path& out) {
  return typemerge::test::outputs_of(out, {"typemerge-"});
}

// One unsharded batch of the tree, the reference every recipe must reproduce.
const fs::path& whole() {
  static const fs::path out = [] {
    const fs::path dir = fresh_dir("cluster_whole") / "out";
    const auto run = shell(std::string(TYPEMERGE_EXE) + " batch " + tree().string() +
                           " --preset bone --out " + dir.string());
    EXPECT_EQ(run.exit_code, 5) << run.out;  // two studies fail
    return dir;
  }();
  return out;
}

void expect_like_whole(const fs::path& out) {
  ASSERT_TRUE(fs::exists(out / "summary.json")) << out;
  const json merged = summary_of(out / "summary.json");
  const json reference = summary_of(whole() / "summary.json");
  EXPECT_EQ(comparable(merged["results"]), comparable(reference["results"]));
  EXPECT_EQ(merged["studies"], 6);
  EXPECT_EQ(merged["failed"], 2);
  const auto outputs = outputs_of(out);
  EXPECT_EQ(outputs.size(), 4u);
  EXPECT_TRUE(outputs == outputs_of(whole())) << "outputs differ from the unsharded batch's";
  // The broken studies are reported with their reasons.
  int broken = 0;
  for (const auto& r : merged["results"]) {
    if (r["status"] != "failed") continue;
    const std::string reason = r["reason"];
    broken += reason.find("Hounsfield") != std::string::npos ||
              reason.find("missing slice") != std::string::npos;
  }
  EXPECT_EQ(broken, 2) << merged.dump(1);
}

// Every output present is a whole STL (its size matches its triangle count), and no
// temporary lies outside the work folders.
void expect_no_partial_file(const fs::path& out) {
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    const std::string relative = entry.path().lexically_relative(out).generic_string();
    if (relative.rfind(".typemerge/work", 0) == 0) continue;
    EXPECT_EQ(relative.find(".partial"), std::string::npos) << relative;
    EXPECT_EQ(relative.find(".tmp"), std::string::npos) << relative;
    if (entry.path().extension() != ".stl") continue;
    const std::string bytes = read_file_bytes(entry.path());
    ASSERT_GE(bytes.size(), 84u) << relative;
    std::uint32_t triangles = 0;
    std::memcpy(&triangles, bytes.data() + 80, 4);
    EXPECT_EQ(bytes.size(), 84u + 50u * triangles) << relative << " is cut off";
  }
}

TEST(ClusterParallel, TheReadmesGnuParallelLinesGiveTheUnshardedOutputs) {
  if (!find_program("parallel")) {
    if (under_ci()) FAIL() << "GNU parallel is not installed (scripts/install_deps.sh installs it)";
    GTEST_SKIP() << "GNU parallel is not installed (apt-get install parallel)";
  }
  const fs::path work = fresh_dir("cluster_parallel");
  const fs::path out = work / "out";
  const auto start = Clock::now();
  for (const char* prefix : {"parallel -j2 typemerge batch", "typemerge batch --merge-summaries"}) {
    const std::string line = readme_line(prefix, tree(), out);
    const auto run = shell("cd " + work.string() + " && " + with_typemerge_on_path() + " " + line);
    // Exit codes: parallel's is the number of failed jobs (shards holding a failed study);
    // the merge's is 5 (some failed).
    EXPECT_NE(run.exit_code, -1) << line << "\n" << run.out;
  }
  std::cerr << "parallel: 8 shards and the merge in "
            << std::chrono::duration<double>(Clock::now() - start).count() << " s\n";
  for (int k = 1; k <= 8; ++k) {
    EXPECT_TRUE(fs::exists(out / ("summary.shard-" + std::to_string(k) + "-of-8.json"))) << k;
  }
  expect_like_whole(out);
}

// ---------------------------------------------------------------------------------------------
// A single-node Slurm cluster in a temporary folder.

class SlurmCluster {
 public:
  // Starts the daemons and waits for the node to be idle; returns an empty string or what
  // went wrong (with the daemons' logs).
  std::string start(const fs::path& dir) {
    dir_ = dir;
    for (const char* name : {"munged", "slurmctld", "slurmd", "sbatch", "squeue", "scontrol",
                             "scancel", "sinfo"}) {
      if (!find_program(name)) return std::string("not installed: ") + name;
    }
    fs::create_directories(dir / "munge");
    fs::create_directories(dir / "state");
    fs::create_directories(dir / "spool");
    fs::permissions(dir / "munge", fs::perms(0755));  // munged: the socket's folder open to all
    {
      std::ifstream random("/dev/urandom", std::ios::binary);
      std::string key(1024, '\0');
      random.read(key.data(), static_cast<std::streamsize>(key.size()));
      std::ofstream(dir / "munge" / "munge.key", std::ios::binary) << key;
      fs::permissions(dir / "munge" / "munge.key", fs::perms::owner_read);
    }
    const fs::path socket = dir / "munge" / "munge.socket";
    pids_.push_back(spawn({*find_program("munged"), "--foreground", "--socket=" + socket.string(),
                           "--key-file=" + (dir / "munge/munge.key").string(),
                           "--pid-file=" + (dir / "munge/munged.pid").string(),
                           "--log-file=" + (dir / "munge/munged.log").string(),
                           "--seed-file=" + (dir / "munge/munged.seed").string()},
                          dir / "munged.out"));
    if (!wait_until([&] { return fs::exists(socket); }, std::chrono::seconds(20))) {
      return "munged did not start:\n" + logs();
    }
    const std::string problem = write_config(socket);
    if (!problem.empty()) return problem;
    ::setenv("SLURM_CONF", (dir / "slurm.conf").c_str(), 1);
    pids_.push_back(spawn({*find_program("slurmctld"), "-D"}, dir / "slurmctld.out"));
    pids_.push_back(spawn({*find_program("slurmd"), "-D"}, dir / "slurmd.out"));
    if (!wait_until([] { return shell("sinfo -h -o %t").out.find("idle") != std::string::npos; },
                    std::chrono::seconds(60))) {
      return "the Slurm node did not become idle:\n" + shell("sinfo -N -l").out + logs();
    }
    return "";
  }

  // Cancels what is left, then stops the daemons by their pids (SIGTERM, then SIGKILL).
  void stop() {
    if (pids_.size() == 3) {
      shell("scancel --user=root");
      wait_until([] { return shell("squeue -h").out.empty(); }, std::chrono::seconds(20));
    }
    for (auto pid = pids_.rbegin(); pid != pids_.rend(); ++pid) ::kill(*pid, SIGTERM);
    for (const pid_t pid : pids_) {
      int status = 0;
      const bool ended = wait_until([&] { return ::waitpid(pid, &status, WNOHANG) == pid; },
                                    std::chrono::seconds(10));
      if (!ended) {
        ::kill(pid, SIGKILL);
        ::waitpid(pid, &status, 0);
      }
    }
    pids_.clear();
  }

  std::string logs() const {
    std::string text;
    for (const char* name : {"munged.out", "munge/munged.log", "slurmctld.out", "slurmctld.log",
                             "slurmd.out", "slurmd.log"}) {
      std::string log = read_file_bytes(dir_ / name);
      if (log.size() > 3000) log = "..." + log.substr(log.size() - 3000);
      if (!log.empty()) text += "--- " + std::string(name) + "\n" + log + "\n";
    }
    return text;
  }

 private:
  static pid_t spawn(const std::vector<std::string>& arguments, const fs::path& log) {
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (::getppid() != parent) ::_exit(1);  // the test died before prctl
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      std::vector<char*> argv;
      for (const auto& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    return pid;
  }

  static int free_port() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof address;
    ::bind(fd, reinterpret_cast<sockaddr*>(&address), size);
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
    ::close(fd);
    return ntohs(address.sin_port);
  }

  // The node is this machine as `slurmd -C` sees it (CPUs, sockets, memory), at 127.0.0.1.
  // The array script asks for 2 CPUs a task: a one-CPU machine is declared with two
  // (config_overrides: slurmd then trusts the configuration).
  std::string write_config(const fs::path& socket) {
    const Shell probe = shell(find_program("slurmd")->string() + " -C");
    std::smatch node;
    if (!std::regex_search(probe.out, node, std::regex("NodeName=(\\S+) (.*RealMemory=\\d+)"))) {
      return "slurmd -C did not describe this machine:\n" + probe.out;
    }
    const std::string host = node[1];
    std::string resources = node[2];
    std::string overrides;
    if (std::regex_search(resources, std::regex("^CPUs=1 "))) {
      resources = "CPUs=2 RealMemory=" + std::regex_replace(resources, std::regex(".*RealMemory="), "");
      overrides = "SlurmdParameters=config_overrides\n";
    }
    const fs::path d = dir_;
    std::ofstream conf(d / "slurm.conf");
    conf << "ClusterName=typemerge-test\n"
         << "SlurmctldHost=" << host << "(127.0.0.1)\n"
         << "SlurmctldPort=" << free_port() << "\n"
         << "SlurmdPort=" << free_port() << "\n"
         << "SlurmUser=root\nSlurmdUser=root\n"
         << "AuthType=auth/munge\nCredType=cred/munge\n"
         << "AuthInfo=socket=" << socket.string() << "\n"
         << "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n"
         << "SelectType=select/cons_tres\nSelectTypeParameters=CR_CPU_Memory\n"
         << "SchedulerType=sched/builtin\nSchedulerParameters=sched_min_interval=100000,batch_sched_delay=0\n"
         << "MpiDefault=none\nReturnToService=2\n"
         << "AccountingStorageType=accounting_storage/none\n"
         << "JobAcctGatherType=jobacct_gather/none\nJobCompType=jobcomp/none\n"
         << "MinJobAge=600\nKillWait=5\nInactiveLimit=0\n"
         << "StateSaveLocation=" << (d / "state").string() << "\n"
         << "SlurmdSpoolDir=" << (d / "spool").string() << "\n"
         << "SlurmctldPidFile=" << (d / "slurmctld.pid").string() << "\n"
         << "SlurmdPidFile=" << (d / "slurmd.pid").string() << "\n"
         << "SlurmctldLogFile=" << (d / "slurmctld.log").string() << "\n"
         << "SlurmdLogFile=" << (d / "slurmd.log").string() << "\n"
         << overrides
         << "NodeName=" << host << " NodeAddr=127.0.0.1 " << resources << " State=UNKNOWN\n"
         << "PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n";
    return "";
  }

  fs::path dir_;
  std::vector<pid_t> pids_;
};

// The states of a job (one per array task) from scontrol, e.g. {"COMPLETED", "FAILED"}.
std::vector<std::string> job_states(const std::string& job) {
  const std::string text = shell("scontrol -o show job " + job).out;
  std::vector<std::string> states;
  const std::regex state("JobState=(\\S+)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), state);
       it != std::sregex_iterator(); ++it) {
    states.push_back((*it)[1]);
  }
  return states;
}

bool job_ended(const std::string& job) {
  const auto states = job_states(job);
  if (states.empty()) return false;
  for (const std::string& s : states) {
    if (s == "PENDING" || s == "RUNNING" || s == "CONFIGURING" || s == "COMPLETING" ||
        s == "SUSPENDED" || s == "REQUEUED" || s == "RESIZING") {
      return false;
    }
  }
  return true;
}

class Slurm : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (::geteuid() != 0) {
      problem_ = "not root: the test runs slurmd and munged as root";
    } else {
      dir_ = fresh_dir("cluster_slurm");
      const auto start = Clock::now();
      problem_ = cluster_.start(dir_);
      startup_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
      startup_failed_ = !problem_.empty() && problem_.rfind("not installed", 0) != 0;
    }
  }
  static void TearDownTestSuite() { cluster_.stop(); }

  void SetUp() override {
    if (problem_.empty()) return;
    if (startup_failed_ || under_ci()) FAIL() << "Slurm: " << problem_;
    GTEST_SKIP() << "Slurm cannot start here: " << problem_
                 << (::geteuid() == 0 ? " (scripts/install_deps.sh installs slurm-wlm and munge)"
                                      : " (run the test as root)");
  }

  // Runs a README line in `work` (job logs land there), typemerge on PATH, 1G a job.
  static Shell run_line(const fs::path& work, const std::string& line) {
    return shell("cd " + work.string() + " && " + with_typemerge_on_path() +
                 " SBATCH_MEM_PER_NODE=1G " + line);
  }

  static bool wait_for(const std::string& job) {
    return wait_until([&] { return job_ended(job); }, kJobDeadline);
  }

  static std::string job_logs(const fs::path& work) {
    std::string text;
    for (const auto& entry : fs::directory_iterator(work)) {
      if (entry.path().extension() == ".out") {
        text += "--- " + entry.path().filename().string() + "\n" + read_file_bytes(entry.path());
      }
    }
    return text + shell("scontrol -o show job").out + cluster_.logs();
  }

  static std::string submitted_job(const std::string& sbatch_output) {
    std::smatch id;
    if (!std::regex_search(sbatch_output, id, std::regex("Submitted batch job (\\d+)"))) return "";
    return id[1].str();
  }

  static inline SlurmCluster cluster_;
  static inline fs::path dir_;
  static inline std::string problem_;
  static inline bool startup_failed_ = false;
  static inline double startup_seconds_ = 0;
};

std::string shard_summary(int k) {
  return "summary.shard-" + std::to_string(k) + "-of-" + std::to_string(kShards) + ".json";
}

// The shard of the study converted into `output_folder` (from the unsharded summary).
int shard_of(const std::string& output_folder) {
  const json summary = summary_of(whole() / "summary.json");
  for (const auto& r : summary["results"]) {
    if (r["output"] == output_folder) {
      for (int k = 1; k <= kShards; ++k) {
        if (typemerge::app::in_shard(r["study"].get<std::string>(), k, kShards)) return k;
      }
    }
  }
  ADD_FAILURE() << "no study converted into " << output_folder;
  return 1;
}

// submit.sh as the README runs it: the array and the merge, whose summary and outputs are
// the unsharded batch's; then the README's resubmission of one task finds its studies up to
// date and rewrites nothing.
TEST_F(Slurm, TheArrayAndItsMergeGiveTheUnshardedBatchAndAResubmittedTaskRewritesNothing) {
  std::cerr << "slurm: the cluster started in " << startup_seconds_ << " s\n";
  whole();
  const fs::path work = fresh_dir("cluster_array");
  const fs::path out = work / "out";
  auto start = Clock::now();
  const auto submit =
      run_line(work, readme_line("TYPEMERGE_SHARDS=16 scripts/slurm/submit.sh", tree(), out));
  ASSERT_EQ(submit.exit_code, 0) << submit.out;
  std::smatch ids;
  ASSERT_TRUE(std::regex_search(submit.out, ids,
                                std::regex("array job (\\d+):[^\n]*\nmerge job (\\d+):")))
      << submit.out;
  const std::string array_job = ids[1], merge_job = ids[2];
  ASSERT_TRUE(wait_for(merge_job)) << "the merge job did not end in time\n" << job_logs(work);
  std::cerr << "slurm: " << kShards << " array tasks and the merge in "
            << std::chrono::duration<double>(Clock::now() - start).count() << " s\n";
  EXPECT_EQ(job_states(array_job).size(), static_cast<std::size_t>(kShards));
  for (int k = 1; k <= kShards; ++k) {
    EXPECT_TRUE(fs::exists(out / shard_summary(k))) << k << "\n" << job_logs(work);
  }
  expect_like_whole(out);
  if (HasFailure()) std::cerr << job_logs(work);

  // Resubmit the task of study E, then the README's merge step.
  const int k = shard_of("siteC/studyE/s1");
  const json before = summary_of(out / shard_summary(k));
  std::map<std::string, fs::file_time_type> times;
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    if (entry.is_regular_file() && entry.path().filename().string().rfind("summary", 0) != 0) {
      times[entry.path().string()] = entry.last_write_time();
    }
  }
  const auto outputs = outputs_of(out);
  start = Clock::now();
  std::string line = readme_line("TYPEMERGE_SHARDS=16 sbatch --array=5", tree(), out);
  line.replace(line.find("--array=5"), 9, "--array=" + std::to_string(k));
  const auto rerun = run_line(work, line);
  const std::string rerun_job = submitted_job(rerun.out);
  ASSERT_FALSE(rerun_job.empty()) << line << "\n" << rerun.out;
  ASSERT_TRUE(wait_for(rerun_job)) << job_logs(work);
  std::cerr << "slurm: a resubmitted task in "
            << std::chrono::duration<double>(Clock::now() - start).count() << " s\n";
  const json after = summary_of(out / shard_summary(k));
  EXPECT_EQ(after["converted"], 0) << after.dump(1);
  EXPECT_GE(after["up_to_date"].get<int>(), 1);
  EXPECT_EQ(after["up_to_date"], before["converted"].get<int>() + before["up_to_date"].get<int>());
  EXPECT_EQ(comparable(after["results"]), comparable(before["results"]));
  EXPECT_FALSE(fs::exists(out / "summary.shard-1-of-1.json"));
  for (const auto& [file, time] : times) {
    EXPECT_TRUE(fs::exists(file) && fs::last_write_time(file) == time) << file << " rewritten";
  }
  EXPECT_EQ(outputs_of(out), outputs);

  fs::remove(out / "summary.json");
  const auto merge = run_line(work, readme_line("sbatch --wrap \"typemerge batch --merge", tree(), out));
  const std::string merge_again = submitted_job(merge.out);
  ASSERT_FALSE(merge_again.empty()) << merge.out;
  ASSERT_TRUE(wait_for(merge_again)) << job_logs(work);
  expect_like_whole(out);
}

// The task holding the big study F is cancelled with scancel while it converts F: no partial
// file is left, and the README's resubmission finishes the shard with the unsharded outputs.
TEST_F(Slurm, ACancelledTaskLeavesNoPartialFileAndAResubmissionFinishesIt) {
  whole();
  const fs::path work = fresh_dir("cluster_cancel");
  const fs::path out = work / "out";
  const fs::path log = work / "events.jsonl";
  const int k = shard_of(kBigStudy);
  std::string line = readme_line("TYPEMERGE_SHARDS=16 sbatch --array=5", tree(), out);
  line.replace(line.find("--array=5"), 9, "--array=" + std::to_string(k));
  line += " --threads 1";  // F converts slower (outputs do not depend on it): a wider window
  const auto submit = run_line(work, line + " --log " + log.string());
  const std::string job = submitted_job(submit.out);
  ASSERT_FALSE(job.empty()) << submit.out;

  const std::string started = R"("event":"study_start","study":")";
  const std::string big_output = std::string(R"("output":")") + kBigStudy + "\"";
  const bool converting = wait_until(
      [&] {
        const std::string events = read_file_bytes(log);
        for (std::size_t at = events.find(started); at != std::string::npos;
             at = events.find(started, at + 1)) {
          const std::size_t end = events.find('\n', at);
          if (events.substr(at, end - at).find(big_output) != std::string::npos) return true;
        }
        return false;
      },
      kJobDeadline);
  ASSERT_TRUE(converting) << "no study_start event for " << kBigStudy << "\n"
                          << read_file_bytes(log) << job_logs(work);
  const auto cancel = shell("scancel " + job);
  EXPECT_EQ(cancel.exit_code, 0) << cancel.out;
  ASSERT_TRUE(wait_for(job)) << job_logs(work);
  EXPECT_EQ(job_states(job), std::vector<std::string>{"CANCELLED"});
  std::istringstream events(read_file_bytes(log));
  for (std::string event; std::getline(events, event);) {
    EXPECT_FALSE(event.find(R"("event":"study_end")") != std::string::npos &&
                 event.find(big_output) != std::string::npos)
        << "F ended before the cancel: " << event;
  }
  EXPECT_FALSE(fs::exists(out / kBigStudy / "bone.stl")) << "F converted before the cancel";
  expect_no_partial_file(out);
  // scancel's SIGTERM reached the batch, which stopped cleanly and said so.
  const json cancelled = summary_of(out / shard_summary(k));
  EXPECT_EQ(cancelled["interrupted"], 1) << cancelled.dump(1);

  // Resubmitted, the task converts what is left; its outputs are the unsharded batch's.
  const auto again = run_line(work, line);
  const std::string job_again = submitted_job(again.out);
  ASSERT_FALSE(job_again.empty()) << again.out;
  ASSERT_TRUE(wait_for(job_again)) << job_logs(work);
  const json summary = summary_of(out / shard_summary(k));
  std::map<std::string, std::string> expected;
  for (const auto& [file, bytes] : outputs_of(whole())) {
    for (const auto& r : summary["results"]) {
      const std::string folder = r["output"];
      if (!folder.empty() && file.rfind(folder + "/", 0) == 0) expected[file] = bytes;
    }
  }
  EXPECT_TRUE(expected.count(std::string(kBigStudy) + "/bone.stl"));
  EXPECT_TRUE(outputs_of(out) == expected) << summary.dump(1);
  EXPECT_TRUE(fs::is_empty(out / ".typemerge" / "work"));
  expect_no_partial_file(out);
  if (HasFailure()) std::cerr << job_logs(work);
}

}  // namespace
