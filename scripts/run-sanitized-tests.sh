#!/usr/bin/env bash
# Runs every test program of a sanitizer build (make test-sanitize) with the Catch filter
# ~[slow], JOBS at a time; any sanitizer report fails the program (halt_on_error) and the run.
# Usage: run-sanitized-tests.sh BUILD_DIR JOBS
set -uo pipefail
build=${1:?build dir}
jobs=${2:-2}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
if [ -f "$(dirname "$0")/lsan.supp" ]; then
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$(cd "$(dirname "$0")" && pwd)/lsan.supp:print_suppressions=0}
fi
logs="$build/sanitize-logs"
rm -rf "$logs" && mkdir -p "$logs"
start=$(date +%s)
ls "$build"/*_test | xargs -P "$jobs" -I{} bash -c \
  'name=$(basename {}); if {} "~[slow]" > "'"$logs"'/$name.log" 2>&1; then echo "ok      $name"; else echo "FAILED  $name (log: '"$logs"'/$name.log)"; fi' \
  | tee "$logs/summary.txt"
end=$(date +%s)
echo "sanitized tests: $((end - start)) s"
if grep -q '^FAILED' "$logs/summary.txt"; then
  grep -l 'ERROR: AddressSanitizer\|runtime error:\|ERROR: LeakSanitizer' "$logs"/*.log 2>/dev/null | sed 's/^/sanitizer report in /'
  exit 1
fi
