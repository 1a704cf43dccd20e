# Fascicle: two commands for a new user on Debian 12.
#   make demo   installs dependencies, builds, runs the main job on a generated sample
#   make test   installs dependencies, builds, runs the unit tests and a fixed sample of corpus
#               muscles (CTest label unit)
#   make test-corpus   the corpus tier: every corpus muscle, the [slow] and [stress] cases (label corpus)
#   make install PREFIX=DIR   builds and installs the program in DIR/bin, its libraries in DIR/lib
#   make bench   every bench program into docs/bench/*.json, then docs/BENCHMARKS.md from them
#                (scripts/bench.sh; BENCH_SECTIONS="repair sphere ..." for some parts only)
# Reliability (docs/RELIABILITY.md):
#   make test-sanitize   the test suite built with ASan+UBSan (-O1 -g1) in build-sanitize/ ([slow], [no-sanitize] excluded)
#   make test-sanitize-geometry   the CGAL-free tests only under ASan+UBSan (minutes, for CI)
#   make fuzz            libFuzzer targets for every reader in build-fuzz/ (needs clang),
#                        FUZZ_SECONDS per target (default 600), FUZZ_JOBS targets at once
#   make stress SEEDS=N  the defect-injection stress test with N seeds per muscle
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
BUILD_TYPE ?= Release
DEMO_DIR ?= demo-out
PREFIX ?= /usr/local

.PHONY: all deps configure build test test-corpus bench demo install clean test-sanitize sanitize-build test-sanitize-geometry fuzz stress

SANITIZE_BUILD ?= build-sanitize
FUZZ_BUILD ?= build-fuzz
FUZZ_SECONDS ?= 600
FUZZ_JOBS ?= 1
SEEDS ?= 20

all: build

deps:
	@bash scripts/install-deps.sh

configure: deps
	@cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) -DFASCICLE_STRICT=ON > /dev/null

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

test: build
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L unit

test-corpus: build
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L corpus

bench: build
	@bash scripts/bench.sh $(BUILD) ../shared/data docs/bench

install: build
	@cmake --install $(BUILD) --prefix $(PREFIX)

demo: build
	@bash scripts/demo.sh $(BUILD)/fascicle $(DEMO_DIR)

# Whole suite under AddressSanitizer + UndefinedBehaviorSanitizer. Each test program runs directly
# with the Catch filter ~[slow]~[no-sanitize] (the long corpus runs would take hours under ASan;
# [no-sanitize]: the few other cases too slow under ASan, listed in docs/RELIABILITY.md).
# -O1 -g1: the sanitizers need no -O3 (-O1 is what the ASan documentation recommends), the CGAL
# translation units compile faster at -O1, and -g1 keeps file:line in the reports without full
# debug info. The compiler launcher is
# ccache (top-level CMakeLists.txt) with CCACHE_BASEDIR set so worktrees share objects.
# -Wno-maybe-uninitialized: with -fsanitize=address g++ 12 reports false "may be used
# uninitialized" inside CGAL's headers (Point_inside_vertical_ray_cast.h), fatal under -Werror.
SANITIZE_FLAGS ?= -O1 -g1 -DNDEBUG
# SANITIZE_DEADLINE (seconds since the epoch, default 0 = none): programs not started by then
# are listed as not run (.ci/run passes its time budget).
SANITIZE_DEADLINE ?= 0
test-sanitize: deps sanitize-build
	@bash scripts/run-sanitized-tests.sh $(SANITIZE_BUILD) $(JOBS) 3600 $(SANITIZE_DEADLINE)

# The build of test-sanitize alone (to build at a low priority while doing something else).
sanitize-build:
	@CCACHE_BASEDIR=$${CCACHE_BASEDIR:-$(dir $(CURDIR))} cmake -S . -B $(SANITIZE_BUILD) \
	  -DCMAKE_BUILD_TYPE=Release -DFASCICLE_STRICT=ON -DFASCICLE_SANITIZE=ON \
	  "-DCMAKE_CXX_FLAGS_RELEASE=$(SANITIZE_FLAGS)" "-DCMAKE_CXX_FLAGS=-Wno-maybe-uninitialized" > /dev/null
	@CCACHE_BASEDIR=$${CCACHE_BASEDIR:-$(dir $(CURDIR))} cmake --build $(SANITIZE_BUILD) -j $(JOBS)

# The CGAL-free tests (readers, writers, injector) under ASan+UBSan; tests that start the program
# use the normal build's.
test-sanitize-geometry: build
	@bash scripts/sanitize-geometry-tests.sh $(SANITIZE_BUILD)-geometry $(BUILD) $(JOBS)

# libFuzzer targets for every reader, built from geometry/ only (no CGAL) with clang.
fuzz:
	@bash fuzz/run.sh $(FUZZ_BUILD) $(FUZZ_SECONDS) $(FUZZ_JOBS)

# The defect-injection stress test with SEEDS seeds per muscle (make test runs a fixed few).
stress: build
	@FASCICLE_STRESS_SEEDS=$(SEEDS) $(BUILD)/reliability_stress_test "[stress]"

clean:
	rm -rf $(BUILD) $(DEMO_DIR) $(SANITIZE_BUILD) $(FUZZ_BUILD)
