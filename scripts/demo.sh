#!/usr/bin/env bash
# make demo: generate the built-in sample muscle (with CT-like defects), run the main job on it
# and say where the results are.
set -euo pipefail
exe=${1:-build/fascicle}
out=${2:-demo-out}
mkdir -p "$out"

"$exe" sample -o "$out/sample.off" --log "$out/sample-defects.json"
"$exe" repair "$out/sample.off" -o "$out/sample-repaired.off" --report "$out/repair-report.json"
"$exe" sphere "$out/sample.off" -o "$out/sample-sphere.vtk" --report "$out/sphere-report.json"
"$exe" decompose "$out/sample.off" -o "$out/fibres.vtk" --report "$out/decompose-report.json" \
  --write-repaired "$out/sample-muscle.off"
"$exe" check "$out/fibres.vtk" "$out/sample-muscle.off" --report "$out/check-report.json"
if ! "$exe" render "$out/sample-muscle.off" "$out/fibres.vtk" -o "$out/fibres.png"; then
  echo "(no picture: no OpenGL context on this machine)"
fi

echo
echo "Demo results in $out/:"
for f in "$out"/*; do echo "  $f"; done
