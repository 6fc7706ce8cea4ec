# Warnings and sanitizers for the project's own targets (never for third-party code).
add_library(typemerge_compiler_options INTERFACE)
target_compile_options(typemerge_compiler_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion)
if(TYPEMERGE_WARNINGS_AS_ERRORS)
  target_compile_options(typemerge_compiler_options INTERFACE -Werror)
endif()

if(TYPEMERGE_SANITIZE)
  string(REPLACE ";" "," _sanitizers "${TYPEMERGE_SANITIZE}")
  # Applied globally so that tests and the code under test agree on the runtime.
  add_compile_options(-fsanitize=${_sanitizers} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${_sanitizers})
endif()

# Fuzzing: every target gets coverage instrumentation and ASan/UBSan; the fuzz targets link
# libFuzzer itself (fuzz/CMakeLists.txt). libFuzzer ships with Clang only.
if(TYPEMERGE_BUILD_FUZZERS)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "TYPEMERGE_BUILD_FUZZERS needs Clang (libFuzzer); configure with "
                        "CC=clang CXX=clang++, as scripts/fuzz.sh does")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined)
endif()

find_program(CCACHE_PROGRAM ccache)
if(CCACHE_PROGRAM)
  set(CMAKE_CXX_COMPILER_LAUNCHER "${CCACHE_PROGRAM}")
  set(CMAKE_C_COMPILER_LAUNCHER "${CCACHE_PROGRAM}")
endif()
