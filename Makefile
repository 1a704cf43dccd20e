# Fascicle: two commands for a new user on Debian 12.
#   make demo   installs dependencies, builds, runs the main job on a generated sample
#   make test   installs dependencies, builds, runs the whole test suite
# Reliability (docs/RELIABILITY.md):
#   make test-sanitize   the test suite built with ASan+UBSan in build-sanitize/ ([slow] excluded)
#   make test-sanitize-geometry   the CGAL-free tests only under ASan+UBSan (minutes, for CI)
#   make fuzz            libFuzzer targets for every reader in build-fuzz/ (needs clang),
#                        FUZZ_SECONDS per target (default 600), FUZZ_JOBS targets at once
#   make stress SEEDS=N  the defect-injection stress test with N seeds per muscle
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
BUILD_TYPE ?= Release
DEMO_DIR ?= demo-out

.PHONY: all deps configure build test demo clean test-sanitize test-sanitize-geometry fuzz stress

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
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

demo: build
	@bash scripts/demo.sh $(BUILD)/fascicle $(DEMO_DIR)

# Whole suite under AddressSanitizer + UndefinedBehaviorSanitizer. Each test program runs directly
# with the Catch filter ~[slow] (the long corpus runs would take hours under ASan).
# -Wno-maybe-uninitialized: with -fsanitize=address g++ 12 reports false "may be used
# uninitialized" inside CGAL's headers (Point_inside_vertical_ray_cast.h), fatal under -Werror.
test-sanitize: deps
	@cmake -S . -B $(SANITIZE_BUILD) -DCMAKE_BUILD_TYPE=Release -DFASCICLE_STRICT=ON -DFASCICLE_SANITIZE=ON \
	  "-DCMAKE_CXX_FLAGS=-Wno-maybe-uninitialized" > /dev/null
	@cmake --build $(SANITIZE_BUILD) -j $(JOBS)
	@bash scripts/run-sanitized-tests.sh $(SANITIZE_BUILD) $(JOBS)

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
