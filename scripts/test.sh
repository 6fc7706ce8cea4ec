#!/usr/bin/env bash
# The README's second command: set up, build and run the whole test suite, twice: an optimised
# build, then an AddressSanitizer + UndefinedBehaviorSanitizer build; then a short fuzz run of
# every libFuzzer target (scripts/fuzz.sh, Clang; 20 s each). Real CT data is taken from
# TYPEMERGE_DATA (default: ../shared/data beside the checkout); tests needing it skip without it.
# The optimised build also runs the cluster recipes of docs/cluster.md (cluster_parallel, cluster_slurm:
# a single-node Slurm started by the test, as root; under CI=true it fails instead of skipping);
# the sanitizer build does not register them (they test scripts and Slurm, not new code).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
"$here/scripts/install_deps.sh"
export TYPEMERGE_DATA="${TYPEMERGE_DATA:-$here/../shared/data}"
jobs="$(nproc 2>/dev/null || echo 2)"

"$here/scripts/build.sh" "$here/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DTYPEMERGE_WARNINGS_AS_ERRORS=ON
ctest --test-dir "$here/build" --output-on-failure --parallel "$jobs"

"$here/scripts/build.sh" "$here/build-asan" -DCMAKE_BUILD_TYPE=Debug \
  -DTYPEMERGE_SANITIZE=address,undefined -DTYPEMERGE_WARNINGS_AS_ERRORS=ON
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir "$here/build-asan" --output-on-failure --parallel "$jobs"

# Short fuzz run (about a minute). A missing clang fails here, loudly: fuzz.sh exits non-zero.
"$here/scripts/fuzz.sh" "${TYPEMERGE_FUZZ_SECONDS:-20}" "$here/build-fuzz"
