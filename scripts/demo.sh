#!/usr/bin/env bash
# The README's first command: set up, build, and run typemerge on the shipped sample series:
# list what it holds, write its HU volume (NRRD) and its bone surface (binary STL), check it.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
"$here/scripts/install_deps.sh"
"$here/scripts/build.sh" "$here/build" -DCMAKE_BUILD_TYPE=Release -DTYPEMERGE_BUILD_TESTS=OFF
tm="$here/build/src/app/typemerge"
out="$here/out"
mkdir -p "$out"
"$tm" info "$here/sample_series"
"$tm" volume "$here/sample_series" -o "$out/sample_volume.nrrd"
"$tm" convert "$here/sample_series" --iso 300 -o "$out/sample_bone.stl"
"$tm" stats "$out/sample_bone.stl"
echo "outputs in $out"
