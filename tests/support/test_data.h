// Where the real CT data is, for tests that use it. TYPEMERGE_DATA (environment) wins over the
// folder configured at build time; when neither exists, tests skip with a message naming it.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <optional>

namespace typemerge::test {

inline std::optional<std::filesystem::path> real_data_dir() {
  std::filesystem::path folder;
  if (const char* env = std::getenv("TYPEMERGE_DATA"); env != nullptr && *env != '\0') {
    folder = env;
  } else {
    folder = TYPEMERGE_DEFAULT_DATA;
  }
  std::error_code error;
  if (std::filesystem::is_directory(folder / "ct", error)) return folder;
  return std::nullopt;
}

// Whether this is the optimised build without sanitizers, where heavy checks on big real
// series run (an ASan build takes minutes per surface).
inline bool optimised_build() {
#if defined(NDEBUG) && !defined(__SANITIZE_ADDRESS__)
  return true;
#else
  return false;
#endif
}

}  // namespace typemerge::test

// Binds `var` to the real data folder or skips the test, saying what is missing.
#define TYPEMERGE_REQUIRE_REAL_DATA(var)                                                     \
  const auto var##_optional = ::typemerge::test::real_data_dir();                            \
  if (!var##_optional) {                                                                     \
    GTEST_SKIP() << "real CT data not found: set TYPEMERGE_DATA to the shared data folder "  \
                    "(default " TYPEMERGE_DEFAULT_DATA ")";                                   \
  }                                                                                          \
  const std::filesystem::path var = *var##_optional
