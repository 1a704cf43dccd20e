#!/usr/bin/env bash
# make fuzz: builds the libFuzzer targets (fuzz/CMakeLists.txt) into BUILD_DIR with clang and
# runs each for SECONDS, JOBS targets at a time (niced), seeded from fuzz/seeds/ and the shared
# corpus. Corpora, crash artifacts and logs stay under BUILD_DIR; a summary table is printed
# and written to BUILD_DIR/summary.md. Exits 1 when any target found a crash, leak, timeout or
# oversized allocation (the reproducer is named in the summary).
# Usage: run.sh BUILD_DIR SECONDS JOBS      (FUZZ_TARGETS="off ply" limits the targets)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-build-fuzz}
seconds=${2:-600}
jobs=${3:-1}
targets=${FUZZ_TARGETS:-"off obj stl_ascii stl_binary ply vtk thesis points polylines"}
data=${FASCICLE_DATA_DIR:-$root/../shared/data}
case "$build" in /*) ;; *) build=$root/$build ;; esac

# clang and its libFuzzer runtime are needed here only, so they are installed here and not by
# scripts/install-deps.sh (make test does not need them).
fuzzer_links() {
  local dir
  dir=$(mktemp -d)
  echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' > "$dir/t.cpp"
  clang++ -fsanitize=fuzzer,address,undefined "$dir/t.cpp" -o "$dir/t" > /dev/null 2>&1
  local rc=$?
  rm -rf "$dir"
  return $rc
}
if ! command -v clang++ > /dev/null || ! fuzzer_links; then
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "fuzz: installing clang (libFuzzer)"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends clang
  if ! fuzzer_links; then
    major=$(clang++ -dumpversion | cut -d. -f1)
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "libclang-rt-$major-dev"
  fi
fi

cmake -S "$root/fuzz" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo > /dev/null
nice -n 19 cmake --build "$build" -j "$jobs"

tmp=/tmp
if [ -d /dev/shm ] && [ -w /dev/shm ]; then tmp=/dev/shm; fi
mkdir -p "$build/logs"
run_one() {
  local t=$1
  local corpus="$build/corpus/$t" artifacts="$build/artifacts/$t/"
  mkdir -p "$corpus" "$artifacts"
  python3 "$root/fuzz/make_corpus.py" "$t" "$data" "$corpus" > /dev/null
  local start end rc=0
  start=$(date +%s)
  FUZZ_TMPDIR=$tmp nice -n 19 "$build/fuzz_$t" -max_total_time="$seconds" -rss_limit_mb=2048 \
    -malloc_limit_mb=1024 -timeout=10 -max_len=32768 -dict="$root/fuzz/dict/$t.dict" \
    -artifact_prefix="$artifacts" -print_final_stats=1 "$corpus" > "$build/logs/$t.log" 2>&1 || rc=$?
  end=$(date +%s)
  local execs corpus_files finds
  execs=$(grep -a -o 'stat::number_of_executed_units: *[0-9]*' "$build/logs/$t.log" | tail -n 1 | grep -o '[0-9]*$' || echo "?")
  corpus_files=$(find "$corpus" -type f | wc -l)
  finds=$(find "$artifacts" -type f | wc -l)
  echo "| $t | $execs | $((end - start)) | $corpus_files | $finds | $rc |" > "$build/logs/$t.row"
  echo "fuzz_$t: ${execs} runs in $((end - start)) s, corpus $corpus_files, findings $finds (exit $rc)"
}
export -f run_one
export build seconds data root tmp
printf '%s\n' $targets | xargs -P "$jobs" -I{} bash -c 'run_one {}'

{
  echo "fuzzing $(date -u '+%Y-%m-%d %H:%M UTC'), $seconds s per target, $jobs at a time"
  echo
  echo "| target | executions | seconds | corpus files | findings | exit |"
  echo "|---|---|---|---|---|---|"
  for t in $targets; do cat "$build/logs/$t.row"; done
} > "$build/summary.md"
cat "$build/summary.md"
found=0
for t in $targets; do
  for a in "$build/artifacts/$t/"*; do
    [ -e "$a" ] || continue
    echo "finding: $a (log: $build/logs/$t.log)"
    found=1
  done
done
exit $found
