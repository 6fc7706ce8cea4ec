#!/usr/bin/env bash
# The README's first command: set up, build, and run typemerge on the shipped sample series.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
"$here/scripts/install_deps.sh"
"$here/scripts/build.sh" "$here/build" -DCMAKE_BUILD_TYPE=Release -DTYPEMERGE_BUILD_TESTS=OFF
mkdir -p "$here/out"
"$here/build/src/app/typemerge" info "$here/sample_series"
"$here/build/src/app/typemerge" volume "$here/sample_series" -o "$here/out/sample_volume.nrrd"
echo "wrote $here/out/sample_volume.nrrd"
