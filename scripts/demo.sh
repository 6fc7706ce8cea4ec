#!/usr/bin/env bash
# The README's first command: set up, build, and run typemerge on the shipped sample series:
# list what it holds, then write its bone and skin surfaces (binary STL, LPS mm) with PNG
# previews and a JSON report into out/ (crossing triangles counted), and check the bone surface
# (defects and crossing pairs).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
"$here/scripts/install_deps.sh"
"$here/scripts/build.sh" "$here/build-release" -DCMAKE_BUILD_TYPE=Release -DTYPEMERGE_BUILD_TESTS=OFF
tm="$here/build-release/src/app/typemerge"
out="$here/out"
mkdir -p "$out"
"$tm" info "$here/sample_series"
"$tm" convert "$here/sample_series" --preset bone,skin -o "$out" --preview --check-intersections \
  --report "$out/report.json"
"$tm" stats --self-intersections "$out/bone.stl"
echo "outputs in $out: bone.stl skin.stl bone.png skin.png report.json"
