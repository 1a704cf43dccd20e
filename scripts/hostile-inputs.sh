#!/usr/bin/env bash
# Hostile input at scale (docs/RELIABILITY.md, "Resource limits"): files of garbage under every
# mesh extension and a muscle plus a million tiny tetrahedra, each run by the real program under
# /usr/bin/time -v; prints one Markdown table row per run (exit code, peak RSS, wall clock, the
# error line) and whether the run met its contract. Every large file is deleted at the end.
#
# Usage: scripts/hostile-inputs.sh [BUILD_DIR] [WORK_DIR] [GARBAGE_BYTES] [TETRAHEDRA]
#   defaults: build, /tmp/fascicle-hostile, 2G (head -c syntax), 1000000
#   MUSCLE=path overrides the muscle (default: LHDL psoas from ../shared/data).
# Contract: garbage -> a non-zero exit code other than 1 (internal), exactly one line on stderr
# starting "fascicle: error:", no output file. Muscle + tetrahedra -> exit 0 with the muscle kept
# (the output has the faces of the muscle repaired alone) or a clean refusal as above.
# Exits 1 when any run breaks its contract.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "${1:-build}" && pwd)
work=${2:-/tmp/fascicle-hostile}
size=${3:-2G}
tets=${4:-1000000}
muscle=${MUSCLE:-$here/../../shared/data/muscles/lhdl/LHDL_R_M090_Psoas_smooth.415.vtk}
fascicle=$build/fascicle
[ -x "$fascicle" ] || { echo "no $fascicle" >&2; exit 2; }
mkdir -p "$work"
trap 'rm -rf "$work"' EXIT
broken=0

# run LABEL EXPECT OUTPUT COMMAND...: EXPECT is "error" (clean refusal) or "ok|error".
run() {
  local label=$1 expect=$2 output=$3
  shift 3
  rm -f "$output"
  /usr/bin/time -v -o "$work/time.txt" "$@" > /dev/null 2> "$work/stderr.txt"
  local rc=$?
  local wall rss lines first verdict=ok
  wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$work/time.txt")
  rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$work/time.txt")
  lines=$(wc -l < "$work/stderr.txt")
  first=$(head -c 300 "$work/stderr.txt" | head -n 1 | sed 's/|/\\|/g')
  if [ "$rc" -eq 0 ]; then
    [[ $expect == ok* ]] || verdict=BROKEN
  else
    { [ "$rc" -ne 1 ] && [ "$lines" -eq 1 ] && [[ $first == "fascicle: error: "* ]] && [ ! -e "$output" ]; } || verdict=BROKEN
  fi
  [ "$verdict" = ok ] || broken=1
  printf '| %s | %s | %s MB | %s | %s | %s |\n' "$label" "$rc" "$((rss / 1024))" "$wall" "$first" "$verdict"
}

# garbage KIND: one file of $size bytes, hard-linked under every extension (no extra disk).
garbage() {
  local kind=$1 file=$work/garbage
  case $kind in
    bytes) head -c "$size" /dev/urandom > "$file" ;;
    text | line)
      # Printable ASCII (and for "text" newlines, about one byte in 96) from /dev/urandom.
      python3 - "$file" "$size" "$kind" <<'PY'
import os, sys
path, size, kind = sys.argv[1], sys.argv[2], sys.argv[3]
units = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
n = int(size[:-1]) * units[size[-1]] if size[-1] in units else int(size)
chars = bytes(range(32, 127)) + (b"\n" if kind == "text" else b"")
table = bytes(chars[b % len(chars)] for b in range(256))
with open(path, "wb") as out:
    while n > 0:
        chunk = os.urandom(min(n, 64 << 20)).translate(table)
        out.write(chunk)
        n -= len(chunk)
PY
      ;;
  esac
  for ext in off obj stl ply vtk; do
    ln -f "$file" "$work/$kind.$ext"
    run "repair, $size $kind, .$ext" error "$work/out.off" "$fascicle" --quiet repair "$work/$kind.$ext" -o "$work/out.off"
    run "decompose, $size $kind, .$ext" error "$work/out.vtk" "$fascicle" --quiet decompose "$work/$kind.$ext" -o "$work/out.vtk"
  done
  # check reads its fibres with the polyline reader (.vtk, .obj) before the muscle.
  for ext in vtk obj; do
    run "check (fibres), $size $kind, .$ext" error "$work/none" "$fascicle" --quiet check "$work/$kind.$ext" "$muscle"
  done
  rm -f "$file" "$work/$kind".*
}

echo "| run | exit | peak RSS | wall (m:ss) | stderr | contract |"
echo "|---|---|---|---|---|---|"
for kind in bytes text line; do garbage "$kind"; done

# One muscle and $tets tiny disjoint tetrahedra beside it.
"$fascicle" --quiet convert "$muscle" -o "$work/muscle.off" || exit 2
"$fascicle" --quiet repair "$work/muscle.off" -o "$work/muscle-alone.off" || exit 2
python3 "$here/make_tiny_components.py" "$work/muscle.off" "$work/components.ply" "$tets" >&2 || exit 2
ls -l "$work/components.ply" >&2
run "repair, muscle + $tets tetrahedra" "ok|error" "$work/components-out.off" \
  "$fascicle" --quiet --time-limit 600 repair "$work/components.ply" -o "$work/components-out.off" \
  --report "$work/components.json"
if [ -e "$work/components-out.off" ]; then
  alone=$(sed -n 2p "$work/muscle-alone.off")
  kept=$(sed -n 2p "$work/components-out.off")
  echo "muscle repaired alone: $alone (V F E); with the tetrahedra: $kept" >&2
  [ "$alone" = "$kept" ] || { echo "BROKEN: the muscle was not kept as repaired alone" >&2; broken=1; }
  python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print({k: j[k] for k in ('status', 'seconds', 'kept_area_share') if k in j})" "$work/components.json" >&2
fi
exit $broken
