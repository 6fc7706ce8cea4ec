#!/usr/bin/env bash
# Installs every Debian 12 package the project builds, tests and benchmarks with.
# Idempotent: packages already present are skipped, so a second run costs one dpkg query.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config
  libdcmtk-dev            # DICOM parsing and the JPEG / JPEG-LS / RLE codecs
  libnifti2-dev           # nifti/: NIfTI-1/2 headers (nifticlib: byte order, qform, sform)
  libopenjp2-7-dev        # JPEG 2000 decoding, which Debian's DCMTK lacks
  libopencv-core-dev libopencv-imgproc-dev libopencv-photo-dev
  libpng-dev              # preview PNGs (not OpenCV imgcodecs: it drags GDAL and 138 libraries)
  libopenmesh-dev         # mesh finishing: components, smoothing, decimation
  libmeshoptimizer-dev    # reduction_bench's meshoptimizer baseline (benchmarks only)
  libcgal-dev             # exact predicates: the self-intersection (crossing) test
  libcli11-dev            # command line
  nlohmann-json3-dev      # reports and `info --json`
  libtbb-dev              # parallel slabs and decoding
  libxxhash-dev           # batch: content keys of input studies
  lib3mf-dev libzip-dev   # 3MF export (lib3MF.pc links -lzip)
  libgtest-dev libgmock-dev libbenchmark-dev
  dcm2niix                # independent reference for the loader tests
  clang libclang-rt-14-dev  # fuzz/: Clang 14 and its libFuzzer + sanitizer runtimes
  locales tzdata          # determinism tests: a comma-decimal locale (localedef), time zones
  time                    # pipeline_bench: peak RSS of convert as its own process (/usr/bin/time)
  parallel                # cluster_parallel: the README's GNU parallel lines, run as written
  slurm-wlm munge         # cluster_slurm: scripts/slurm on a single-node Slurm the test starts
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  echo "installing: ${missing[*]}" >&2
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

# The determinism tests compare outputs under a comma-decimal locale.
if ! locale -a 2>/dev/null | grep -qi '^de_DE\.utf-\?8$'; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  echo "generating locale de_DE.UTF-8" >&2
  $sudo_cmd sed -i 's/^# *\(de_DE.UTF-8 UTF-8\)/\1/' /etc/locale.gen
  grep -q '^de_DE.UTF-8 UTF-8' /etc/locale.gen || echo 'de_DE.UTF-8 UTF-8' | $sudo_cmd tee -a /etc/locale.gen >/dev/null
  $sudo_cmd locale-gen >&2
fi
