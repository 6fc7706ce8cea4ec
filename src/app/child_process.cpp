#include "app/child_process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace typemerge::app {

ChildProcess::ChildProcess(const ChildSpec& spec) {
  if (spec.argv.empty()) throw std::invalid_argument("ChildProcess: no command");
  // Everything the child needs is prepared before fork: between fork and exec only
  // async-signal-safe calls are allowed (the parent has other threads).
  std::vector<char*> argv;
  for (const std::string& arg : spec.argv) argv.push_back(const_cast<char*>(arg.c_str()));
  argv.push_back(nullptr);
  const int output = ::open(spec.output_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (output < 0) {
    throw std::runtime_error("cannot create " + spec.output_file.string() + ": " +
                             std::strerror(errno));
  }
  const int null_input = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const pid_t parent = ::getpid();
  sigset_t all_signals;
  sigemptyset(&all_signals);

  pid_ = ::fork();
  if (pid_ == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);  // the parent died before prctl
    ::setpgid(0, 0);
    ::sigprocmask(SIG_SETMASK, &all_signals, nullptr);
    if (null_input >= 0) ::dup2(null_input, STDIN_FILENO);
    ::dup2(output, STDOUT_FILENO);
    ::dup2(output, STDERR_FILENO);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  const int fork_error = errno;
  ::close(output);
  if (null_input >= 0) ::close(null_input);
  if (pid_ < 0) throw std::runtime_error(std::string("cannot start a process: ") + std::strerror(fork_error));
  ::setpgid(pid_, pid_);  // also from here, so kill() works even before the child ran setpgid
}

ChildProcess::~ChildProcess() {
  if (pid_ > 0 && !result_) {
    kill();
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
  }
}

std::optional<ChildResult> ChildProcess::poll() {
  if (result_ || pid_ <= 0) return result_;
  int status = 0;
  rusage usage{};
  const pid_t done = ::wait4(pid_, &status, WNOHANG, &usage);
  if (done != pid_) return std::nullopt;
  ChildResult result;
  result.exited = WIFEXITED(status);
  result.exit_code = result.exited ? WEXITSTATUS(status) : -1;
  result.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  result.cpu_seconds = double(usage.ru_utime.tv_sec) + double(usage.ru_utime.tv_usec) * 1e-6 +
                       double(usage.ru_stime.tv_sec) + double(usage.ru_stime.tv_usec) * 1e-6;
  result.peak_rss_bytes = std::uint64_t(usage.ru_maxrss) * 1024;  // Linux: kilobytes
  result_ = result;
  return result_;
}

void ChildProcess::kill() {
  if (pid_ > 0 && !result_) {
    ::kill(-pid_, SIGKILL);
    ::kill(pid_, SIGKILL);
  }
}

std::filesystem::path current_executable() { return std::filesystem::read_symlink("/proc/self/exe"); }

}  // namespace typemerge::app
