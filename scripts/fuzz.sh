#!/usr/bin/env bash
# Builds the libFuzzer targets with Clang in build-fuzz (ASan + UBSan + coverage) and runs each
# for a while. Usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [BUILD_DIR]
#   scripts/fuzz.sh            # 20 s per target (what scripts/test.sh runs: about 1 min)
#   scripts/fuzz.sh 1800       # a real session: 30 min per target
# Corpora grow in BUILD_DIR/corpus/<target> (seeded by make_seed_corpus); a crash stops the
# run, leaves crash-* / timeout-* / oom-* in BUILD_DIR/findings and fails the script. Replay
# one with: BUILD_DIR/fuzz/<target> FILE
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
seconds="${1:-20}"
build="${2:-$here/build-fuzz}"
jobs="$(nproc 2>/dev/null || echo 2)"

if ! command -v clang >/dev/null || ! command -v clang++ >/dev/null; then
  echo "fuzz.sh: clang/clang++ not found; run scripts/install_deps.sh (packages clang," \
       "libclang-rt-14-dev)" >&2
  exit 1
fi

CC=clang CXX=clang++ cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DTYPEMERGE_BUILD_FUZZERS=ON -DTYPEMERGE_BUILD_TESTS=OFF >/dev/null
targets=(fuzz_dicom_file fuzz_series_geometry fuzz_extract fuzz_nifti fuzz_nrrd fuzz_seg fuzz_zip)
cmake --build "$build" --parallel "$jobs" --target "${targets[@]}" make_seed_corpus

corpus="$build/corpus"
findings="$build/findings"
mkdir -p "$corpus" "$findings"
ASAN_OPTIONS=detect_leaks=1 "$build/fuzz/make_seed_corpus" "$corpus"
# The shared real files, when present, seed the NIfTI and NRRD readers too (copied into the
# build's corpus, never into the project).
shared="${TYPEMERGE_DATA:-$here/../shared/data}"
for f in "$shared"/nifti/*.nii.gz; do [ -f "$f" ] && cp "$f" "$corpus/nifti/"; done
for f in "$shared"/seg/dcmqi/*.nrrd "$shared"/seg/dcmqi/*/nrrd/*.nrrd; do
  [ -f "$f" ] && cp "$f" "$corpus/nrrd/shared_$(basename "$(dirname "$f")")_$(basename "$f")"
done
for f in "$shared"/seg/dcmqi/*.dcm "$shared"/seg/dcmqi/*/seg/*.seg; do
  rel="${f#"$shared"/seg/}"
  [ -f "$f" ] && install -m 644 "$f" "$corpus/seg/shared_${rel//\//_}"
done

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
for target in "${targets[@]}"; do
  name="${target#fuzz_}"
  echo "== $target: ${seconds} s" >&2
  # -rss_limit_mb: libFuzzer's default (2 GB); -timeout: one input taking 10 s is a finding.
  "$build/fuzz/$target" "$corpus/$name" -max_total_time="$seconds" -timeout=10 \
    -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/$name-" \
    2>"$build/$target.log" || {
    tail -n 60 "$build/$target.log" >&2
    echo "fuzz.sh: $target found a problem; reproducer in $findings" >&2
    exit 1
  }
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)|cov:" \
    "$build/$target.log" | tail -n 4 >&2
done
echo "fuzz.sh: no findings" >&2
