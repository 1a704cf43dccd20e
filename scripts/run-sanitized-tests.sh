#!/usr/bin/env bash
# Runs every test program of a sanitizer build (make test-sanitize) with the Catch filter
# ~[slow]~[no-sanitize] (docs/RELIABILITY.md says what each tag leaves out and why), JOBS at a
# time; any sanitizer report fails the program (halt_on_error) and the run. Prints one line per
# program with its wall time and Catch's summary; logs in BUILD_DIR/sanitize-logs/.
# Usage: run-sanitized-tests.sh BUILD_DIR JOBS [PER_PROGRAM_TIMEOUT_S]
set -uo pipefail
build=${1:?build dir}
jobs=${2:-2}
limit=${3:-3600}
logs=$(cd "$build" && pwd)/sanitize-logs
rm -rf "$logs" && mkdir -p "$logs"
# Reports go to files (log_path: one file per reporting process), so that a report from a
# program a test starts (fascicle, the wrap worker) is seen even when the test discards its
# standard error.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1:log_path=$logs/asan}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:log_path=$logs/ubsan}
if [ -f "$(dirname "$0")/lsan.supp" ]; then
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$(cd "$(dirname "$0")" && pwd)/lsan.supp:print_suppressions=0}
fi
export logs limit
start=$(date +%s)
# shellcheck disable=SC2016
ls "$build"/*_test | xargs -P "$jobs" -I{} bash -c '
  name=$(basename {}); t0=$(date +%s)
  timeout "$limit" {} "~[slow]~[no-sanitize]" > "$logs/$name.log" 2>&1; rc=$?
  seconds=$(( $(date +%s) - t0 ))
  summary=$(grep -E "^(All tests passed|test cases:)" "$logs/$name.log" | tail -n 1)
  if [ $rc -eq 0 ]; then echo "ok      $name ${seconds} s: $summary"
  else echo "FAILED  $name (exit $rc, ${seconds} s; log: $logs/$name.log)"; fi' \
  | tee "$logs/summary.txt"
end=$(date +%s)
echo "sanitized tests: $((end - start)) s" | tee -a "$logs/summary.txt"
status=0
if grep -q '^FAILED' "$logs/summary.txt"; then status=1; fi
for report in "$logs"/asan.* "$logs"/ubsan.*; do
  [ -e "$report" ] || continue
  echo "sanitizer report: $report"
  grep -m 3 -E 'ERROR|runtime error|SUMMARY' "$report" | sed 's/^/    /'
  status=1
done
exit $status
