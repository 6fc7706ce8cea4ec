// The process exit codes, documented in README.md ("Exit codes").
#pragma once

#include <string>

namespace typemerge::app {

inline constexpr int kExitOk = 0;
inline constexpr int kExitInputRefused = 1;  // nothing usable in the input, or it was refused
inline constexpr int kExitUsage = 2;         // bad arguments
inline constexpr int kExitOutputFailed = 3;  // an output file could not be written
inline constexpr int kExitInternal = 4;      // a bug: please report it

// Thrown by commands; main prints the message on one line and exits with the code.
struct CommandError {
  int exit_code;
  std::string message;
};

}  // namespace typemerge::app
