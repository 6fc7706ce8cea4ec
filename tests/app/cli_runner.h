// Runs the typemerge executable for the app tests: exit code, stdout and stderr apart, with an
// optional environment prefix ("LC_ALL=C TZ=UTC") and wrapper ("taskset -c 0").
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/scratch_files.h"

namespace typemerge::test {

struct CliRun {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

// `environment` and `wrapper` go before the executable, e.g. run_cli("info DIR", "TZ=UTC").
inline CliRun run_cli(const std::string& arguments, const std::string& environment = "",
                      const std::string& wrapper = "") {
  static int counter = 0;
  const std::filesystem::path err_file =
      std::filesystem::temp_directory_path() /
      ("typemerge_cli_stderr_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  const std::string command = (environment.empty() ? "" : "env " + environment + " ") + wrapper +
                              (wrapper.empty() ? "" : " ") + TYPEMERGE_EXE + " " + arguments +
                              " 2>" + err_file.string();
  CliRun result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer{};
  while (std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) {
    result.out.append(buffer.data(), n);
  }
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.err = read_file_bytes(err_file);
  std::error_code error;
  std::filesystem::remove(err_file, error);
  return result;
}


}  // namespace typemerge::test
