// ChildProcess: one command run in a process of its own, so that a crash, a hang or an
// exhausted memory limit inside it (a third-party decoder, say) ends that command only.
//
// No shell is involved: the arguments go to execv as they are. The child gets its own process
// group, its output in a file, and is killed if the parent
// dies (PR_SET_PDEATHSIG), so a killed batch leaves no orphan writing into its work folders.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace typemerge::app {

struct ChildSpec {
  std::vector<std::string> argv;            // argv[0]: the executable's path
  std::filesystem::path output_file;        // stdout and stderr
};

struct ChildResult {
  bool exited = false;  // false: ended by a signal
  int exit_code = -1;
  int signal = 0;
  double cpu_seconds = 0;           // user + system
  std::uint64_t peak_rss_bytes = 0;
};

class ChildProcess {
 public:
  // Throws std::runtime_error when the process cannot be started.
  explicit ChildProcess(const ChildSpec& spec);
  ~ChildProcess();  // kills and reaps a child still running
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  // Non-blocking; the result once the child has ended (and from then on).
  std::optional<ChildResult> poll();
  // SIGKILL to the child's process group; poll() then reports the signal.
  void kill();

 private:
  pid_t pid_ = -1;
  std::optional<ChildResult> result_;
};

// The path of the running executable (/proc/self/exe), to start copies of this tool.
std::filesystem::path current_executable();

}  // namespace typemerge::app
