#!/usr/bin/env bash
# Runs every test program of a sanitizer build (make test-sanitize) with the Catch filter
# ~[slow]~[no-sanitize] (docs/RELIABILITY.md says what each tag leaves out and why), JOBS at a
# time; any sanitizer report fails the program (halt_on_error) and the run. Prints one line per
# program with its wall time and Catch's summary; logs in BUILD_DIR/sanitize-logs/.
# Usage: run-sanitized-tests.sh BUILD_DIR JOBS [PER_PROGRAM_TIMEOUT_S] [DEADLINE]
# DEADLINE (seconds since the epoch, optional): a time budget. A program is not started after
# it, and one still running then is stopped; both are listed as "not run" or "unfinished", which
# do not fail the run (every program that finishes must still be clean). .ci/run uses it.
# The longest programs start first (measured order, docs/RELIABILITY.md), so that the two
# workers finish together and a budget cut falls on the short ones.
set -uo pipefail
build=${1:?build dir}
jobs=${2:-2}
limit=${3:-3600}
deadline=${4:-0}
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
# The stress test under ASan: every sixth muscle (8 of 47) with a time limit per process that
# fits the slower sanitized program; `make test` runs all 47.
export FASCICLE_STRESS_STRIDE=${FASCICLE_STRESS_STRIDE:-6}
export FASCICLE_STRESS_TIME_LIMIT=${FASCICLE_STRESS_TIME_LIMIT:-600}
# Time budgets the tests give the program (wrap seconds, time limits) times 4: ASan at -O1 makes
# the CGAL-heavy stages several times slower (tests/test_common.h, time_scale).
export FASCICLE_TEST_TIME_SCALE=${FASCICLE_TEST_TIME_SCALE:-4}
export logs limit deadline
first="repair_test reliability_stress_test app_cli_test reliability_spawn_test repair_corpus_test shaders_gpu_test
       fibres_decompose_test reliability_limits_test fibres_untangle_test springs_solver_test"
programs=()
for name in $first; do [ -x "$build/$name" ] && programs+=("$build/$name"); done
for path in "$build"/*_test; do
  case " $(echo $first) " in *" $(basename "$path") "*) continue ;; esac
  programs+=("$path")
done
start=$(date +%s)
# shellcheck disable=SC2016
printf '%s\n' "${programs[@]}" | xargs -P "$jobs" -I{} bash -c '
  name=$(basename {}); t0=$(date +%s)
  if [ "$deadline" -gt 0 ] && [ "$t0" -ge "$deadline" ]; then echo "not run $name (time budget spent)"; exit 0; fi
  run_limit=$limit
  if [ "$deadline" -gt 0 ] && [ $((deadline - t0)) -lt "$run_limit" ]; then run_limit=$((deadline - t0)); fi
  timeout "$run_limit" {} "~[slow]~[no-sanitize]" > "$logs/$name.log" 2>&1; rc=$?
  seconds=$(( $(date +%s) - t0 ))
  summary=$(grep -E "^(All tests passed|test cases:)" "$logs/$name.log" | tail -n 1)
  if [ $rc -eq 0 ]; then echo "ok      $name ${seconds} s: $summary"
  elif [ $rc -eq 124 ] && [ "$run_limit" -lt "$limit" ]; then echo "unfinished $name (stopped at the time budget after ${seconds} s)"
  else echo "FAILED  $name (exit $rc, ${seconds} s; log: $logs/$name.log)"; fi' \
  | tee "$logs/summary.txt"
end=$(date +%s)
echo "sanitized tests: $((end - start)) s; $(grep -c '^ok' "$logs/summary.txt") of ${#programs[@]} programs ran clean" \
  | tee -a "$logs/summary.txt"
status=0
if grep -q '^FAILED' "$logs/summary.txt"; then status=1; fi
for report in "$logs"/asan.* "$logs"/ubsan.*; do
  [ -e "$report" ] || continue
  echo "sanitizer report: $report"
  grep -m 3 -E 'ERROR|runtime error|SUMMARY' "$report" | sed 's/^/    /'
  status=1
done
exit $status
