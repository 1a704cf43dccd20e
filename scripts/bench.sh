#!/usr/bin/env bash
# Today's figures from one command: runs every bench program into docs/bench/*.json, times the
# test tiers, then writes docs/BENCHMARKS.md from those files (scripts/benchmarks.py).
# Rerunning replaces the figures. Run it on a quiet machine: the speed figures are wall times.
# Usage: scripts/bench.sh [BUILD [DATA [OUT]]]   (defaults: build, ../shared/data, docs/bench)
# About 50 minutes on a 2-core machine, of which the templates part is about 20.
#   BENCH_SECTIONS: the parts to run (default all): machine repair sphere springs gpu decompose templates
#   quality tests (and tests-corpus: the corpus tier's time too, about 15 minutes more)
# gpu-h200.json is not made here: it is the last run on an NVIDIA H200 (fascicle bench gpu
# --gl-device 0 --json F on the device machine) and stays until a device run replaces it.
set -euo pipefail
build=$(realpath "${1:-build}")
data=$(realpath "${2:-../shared/data}")
out=${3:-docs/bench}
mkdir -p "$out"
out=$(realpath "$out")
program="$build/fascicle"
sections=${BENCH_SECTIONS:-machine repair sphere springs gpu decompose templates quality tests}
want() { [[ " $sections " == *" $1 "* ]]; }
stamp() { echo "== $1 ($(date -u +%H:%M:%S) UTC, load $(cut -d' ' -f1-3 /proc/loadavg))" >&2; }
# Each part writes a temporary file renamed into place, so a stopped run keeps the old figures.
keep() { mv "$1.tmp" "$1"; }

if want machine; then
  stamp machine
  python3 - "$out/machine.json.tmp" "$program" "$out/machine.json" "$sections" <<'PY'
import json, os, platform, subprocess, sys, datetime
cpu = ""
flags = ""
for line in open("/proc/cpuinfo"):
    if line.startswith("model name") and not cpu:
        cpu = line.split(":", 1)[1].strip()
    if line.startswith("flags") and not flags:
        flags = line.split(":", 1)[1].split()
memory = 0
for line in open("/proc/meminfo"):
    if line.startswith("MemTotal"):
        memory = int(line.split()[1]) * 1024
def git(*args):
    try:
        return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""
machine = {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": round(memory / 2**30, 1),
           "avx2": "avx2" in flags, "avx512": "avx512f" in flags, "os": platform.platform(),
           "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d"),
           "commit": git("rev-parse", "--short", "HEAD"), "dirty": bool(git("status", "--porcelain", "-uno"))}
# Where and when each part was last measured: a run of some parts keeps the others' figures, and
# the tables say which machine and commit gave them.
try:
    parts = json.load(open(sys.argv[3])).get("sections", {})
except (OSError, ValueError):
    parts = {}
stamp = {k: machine[k] for k in ("cpu", "avx512", "commit", "dirty", "date")}
for part in sys.argv[4].split():
    if part != "machine":
        parts[part] = stamp
machine["sections"] = parts
json.dump(machine, open(sys.argv[1], "w"), indent=1)
PY
  keep "$out/machine.json"
fi

if want repair; then
  stamp repair
  "$program" bench repair --data "$data" --json "$out/repair.json.tmp" > /dev/null
  keep "$out/repair.json"
fi

if want sphere; then
  stamp sphere
  "$program" bench sphere --data "$data" --json "$out/sphere.json.tmp" > /dev/null
  keep "$out/sphere.json"
fi

if want springs; then
  stamp springs
  # The thesis's sizes (tables 7.1-7.6) up to 100^3; the speed-accuracy trade at 20^3 and 50^3
  # for the solvers users choose between.
  "$program" bench springs --sections bandwidth,speed,rest,trade --sizes 10,20,50,100 --general-max-size 50 \
    --rest-sizes 5,10 --trade-sizes 20,50 --trade-models 6,26 \
    --trade-solvers verlet-estimate,static-momentum,static-multigrid --trade-limit 60 \
    --json "$out/springs.json.tmp" > /dev/null
  keep "$out/springs.json"
fi

if want gpu; then
  stamp gpu
  # Whatever OpenGL this machine has (Mesa's llvmpipe where there is no GPU).
  "$program" bench gpu --sizes 10,20,40 --readback-sizes 50 --min-seconds 0.5 --stream-mb 64 \
    --json "$out/gpu.json.tmp" > /dev/null
  keep "$out/gpu.json"
fi

if want decompose; then
  stamp decompose
  "$program" bench decompose --data "$data" --repeat 5 --skip-templates --json "$out/decompose.json.tmp" > /dev/null
  keep "$out/decompose.json"
  # Finer surfaces of the same muscle: the map on the simplified surface against the whole one.
  "$program" bench decompose --data "$data" --skip-speed --skip-templates --skip-corpus --surface 1,2,3 \
    --surface-full --json "$out/decompose-surface.json.tmp" > /dev/null
  keep "$out/decompose-surface.json"
fi

if want templates; then
  stamp templates
  # Every template on the LHDL muscles with their landmark files (the longest part: minutes a run
  # where the tries add up).
  "$program" bench decompose --data "$data" --skip-speed --skip-corpus --json "$out/decompose-templates.json.tmp" > /dev/null
  keep "$out/decompose-templates.json"
fi

if want quality; then
  stamp quality
  # The --quality levels on the corpus: batch time and the whole check's figures per level.
  QUALITY_JSON="$out/quality.json.tmp" bash "$(dirname "$0")/quality_levels.sh" "$program" "$data/muscles" \
    "${TMPDIR:-/tmp}/fascicle-bench-quality" > /dev/null
  keep "$out/quality.json"
fi

if want tests || want tests-corpus; then
  stamp tests
  # Wall time of each test tier after the build (ctest -j with the machine's cores).
  labels=unit
  want tests-corpus && labels="unit corpus"
  python3 - "$out/tests.json.tmp" "$build" $labels <<'PY'
import json, os, re, subprocess, sys, time
build = sys.argv[2]
tiers = {}
for label in sys.argv[3:]:
    start = time.monotonic()
    run = subprocess.run(["ctest", "-j", str(os.cpu_count() or 2), "-L", label], cwd=build,
                         capture_output=True, text=True)
    seconds = time.monotonic() - start
    summary = re.search(r"(\d+)% tests passed, (\d+) tests failed out of (\d+)", run.stdout)
    skipped = len(re.findall(r"\*\*\*Skipped", run.stdout))
    tiers[label] = {"seconds": round(seconds, 1), "exit_code": run.returncode,
                    "tests": int(summary.group(3)) if summary else None,
                    "failed": int(summary.group(2)) if summary else None, "skipped": skipped}
json.dump(tiers, open(sys.argv[1], "w"), indent=1)
PY
  keep "$out/tests.json"
fi

stamp tables
python3 "$(dirname "$0")/benchmarks.py" "$out" > "$(dirname "$out")/BENCHMARKS.md.tmp"
mv "$(dirname "$out")/BENCHMARKS.md.tmp" "$(dirname "$out")/BENCHMARKS.md"
