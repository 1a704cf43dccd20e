#!/usr/bin/env bash
# The --quality levels measured on a folder of muscles: for each level, `fascicle batch` with
# default options and that level (timed), then `fascicle check` (every criterion, default
# thresholds) on each muscle's fibres; prints one Markdown table row per level, with each muscle's own
# decompose time (median and largest of its report's seconds.total) beside the batch's.
# Usage: [BATCH_ARGS="--option value ..."] scripts/quality_levels.sh [FASCICLE [MUSCLES [OUT [LEVELS...]]]]
#   defaults: build/fascicle, ../shared/data/muscles, /tmp/fascicle-quality, draft standard fine
# Two runs (say with and without an option in BATCH_ARGS) are compared muscle by muscle by
# scripts/quality_compare.py OUT1/LEVEL OUT2/LEVEL.
set -euo pipefail
program=$(realpath "${1:-build/fascicle}")
muscles=$(realpath "${2:-../shared/data/muscles}")
out=${3:-/tmp/fascicle-quality}
shift $(( $# < 3 ? $# : 3 ))
levels=("$@")
[ ${#levels[@]} -eq 0 ] && levels=(draft standard fine)
mkdir -p "$out"
echo "| level | fibres x points | batch, 2 jobs | per muscle, median / max | decompose passes | whole check passes | segments out | turning > 45 deg | joints > 45 deg | ends < 0.25 | median coverage p95 | median turning |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for level in "${levels[@]}"; do
  dir="$out/$level"
  rm -rf "$dir"
  start=$(date +%s.%N)
  set +e
  # shellcheck disable=SC2086  # BATCH_ARGS: extra batch options, split on spaces
  "$program" -q batch "$muscles" -o "$dir" --jobs 2 --quality "$level" ${BATCH_ARGS:-} > "$dir.log" 2>&1
  set -e
  seconds=$(echo "$(date +%s.%N) - $start" | bc)
  # The whole check on each result, two at a time.
  find "$dir" -name '*.vtk' | sort | while read -r fibres; do
    rel=${fibres#"$dir"/}
    rel=${rel%.vtk}
    mesh=$(ls "$muscles/$rel".* 2>/dev/null | grep -v -E '\.(xyz|log|json)$' | head -1)
    echo "$fibres|$mesh"
  done | xargs -P 2 -I{} bash -c 'f=${1%%|*}; m=${1#*|}; "$0" -q check "$f" "$m" --json > "$f.check.json" 2>/dev/null || true' "$program" {}
  python3 - "$dir" "$level" "$seconds" <<'PY'
import glob, json, statistics, sys
folder, level, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
def load_all(pattern):
    """Every JSON file under the folder matching pattern; a half-written one is left out."""
    out = []
    for path in sorted(glob.glob(folder + "/**/" + pattern, recursive=True)):
        try:
            out.append(json.load(open(path)))
        except ValueError:
            pass
    return out
checks = load_all("*.vtk.check.json")
reports = load_all("*.report.json")
muscles = len(reports)
decompose_ok = sum(1 for r in reports if r.get("status") == "ok")
passed = sum(1 for c in checks if c["pass"])
segments = sum(1 for c in checks if c["crossing_segments"] > 0)
turning = sum(1 for c in checks if c["turning"]["max_deg"] > 45)
ends = sum(1 for c in checks if min(c["ends"]["origin"]["share"], c["ends"]["insertion"]["share"]) < 0.25)
coverage = statistics.median(c["coverage"]["p95"] for c in checks) if checks else float("nan")
turn = statistics.median(c["turning"]["max_deg"] for c in checks) if checks else float("nan")
# Joints over 45 degrees summed over the muscles (the hooks and zigzags a modeller sees), and each
# muscle's own decompose time (its report's seconds.total: repair and every try with its check;
# reading the mesh and writing the fibres are not in it).
joints = sum(c["turning"]["over_45"] for c in checks)
times = [r["seconds"]["total"] for r in reports if isinstance(r.get("seconds"), dict) and "total" in r["seconds"]]
time_median = statistics.median(times) if times else float("nan")
time_max = max(times) if times else float("nan")
shape = "%d x %d" % (checks[0]["fibres"], checks[0]["points"] // checks[0]["fibres"]) if checks else "-"
print("| %s | %s | %.0f s | %.2f / %.1f s | %d of %d | %d of %d | %d | %d | %d | %d | %.2f | %.0f deg |" %
      (level, shape, seconds, time_median, time_max, decompose_ok, muscles, passed, len(checks), segments, turning,
       joints, ends, coverage, turn))
json.dump({"level": level, "lattice": shape, "batch_seconds": seconds, "muscles": muscles,
           "decompose_ok": decompose_ok, "checked": len(checks), "check_pass": passed,
           "segments_out": segments, "turning_over_45": turning, "joints_over_45": joints, "ends_under_025": ends,
           "muscle_seconds_median": time_median, "muscle_seconds_max": time_max,
           "median_coverage_p95": coverage, "median_turning_deg": turn}, open(folder + ".json", "w"))
PY
done
# QUALITY_JSON=F: the rows as one JSON list too (scripts/bench.sh).
if [ -n "${QUALITY_JSON:-}" ]; then
  rows=()
  for level in "${levels[@]}"; do rows+=("$out/$level.json"); done
  python3 -c 'import json, sys; json.dump([json.load(open(p)) for p in sys.argv[2:]], open(sys.argv[1], "w"), indent=1)' \
    "$QUALITY_JSON" "${rows[@]}"
fi
