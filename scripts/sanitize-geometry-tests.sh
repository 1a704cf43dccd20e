#!/usr/bin/env bash
# make test-sanitize-geometry: the CGAL-free part of the suite under ASan + UBSan, fast enough
# for CI. Builds the geometry sources (readers, writers, defect injector, primitives) and the
# test programs that need nothing else into BUILD_DIR with -fsanitize=address,undefined, then
# runs them (Catch filter ~[slow]). Tests that start the `fascicle` program use the one in
# PROGRAM_BUILD (not sanitized; its in-process parts are covered by make test-sanitize).
# Usage: sanitize-geometry-tests.sh BUILD_DIR PROGRAM_BUILD JOBS
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-build-sanitize-geometry}
program_build=${2:-build}
jobs=${3:-2}
case "$build" in /*) ;; *) build=$root/$build ;; esac
case "$program_build" in /*) ;; *) program_build=$root/$program_build ;; esac
data=${FASCICLE_DATA_DIR:-$root/../shared/data}
tests="geometry_io_test geometry_io_errors_test geometry_defects_test geometry_primitives_test geometry_stats_test
       reliability_fuzz_regressions_test reliability_limits_test"
export CXX=${CXX:-c++}
export LAUNCHER=""
if command -v ccache > /dev/null; then LAUNCHER=ccache; fi
export SAN_FLAGS="-std=c++17 -O1 -g -fsanitize=address,undefined -fno-sanitize-recover=undefined
  -fno-omit-frame-pointer -Wall -Wextra -I$root -isystem /usr/include/eigen3
  -DFASCICLE_DATA_DIR=\"$data\" -DFASCICLE_PROGRAM=\"$program_build/fascicle\" -DFASCICLE_SOURCE_DIR=\"$root\"
  -Wno-maybe-uninitialized"
export OBJ_DIR=$build/obj
mkdir -p "$OBJ_DIR"
# Compiles one source into OBJ_DIR (ccache makes an unchanged source cheap).
build_object() {
  # shellcheck disable=SC2086
  $LAUNCHER "$CXX" $SAN_FLAGS -c "$1" -o "$OBJ_DIR/$(basename "$1" .cpp).o"
}
export -f build_object
sources=("$root"/geometry/*.cpp "$root/tests/test_main.cpp")
for t in $tests; do sources+=("$root/tests/$t.cpp"); done
printf '%s\n' "${sources[@]}" | xargs -P "$jobs" -I{} bash -c 'build_object {}'
library=()
for src in "$root"/geometry/*.cpp "$root/tests/test_main.cpp"; do library+=("$OBJ_DIR/$(basename "$src" .cpp).o"); done
for t in $tests; do
  "$CXX" -fsanitize=address,undefined "$OBJ_DIR/$t.o" "${library[@]}" -o "$build/$t"
done
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
status=0
for t in $tests; do
  if "$build/$t" "~[slow]" > "$build/$t.log" 2>&1; then
    echo "ok      $t ($(tail -n 2 "$build/$t.log" | head -n 1))"
  else
    echo "FAILED  $t (log: $build/$t.log)"
    status=1
  fi
done
exit $status
