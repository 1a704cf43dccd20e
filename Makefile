# Fascicle: two commands for a new user on Debian 12.
#   make demo   installs dependencies, builds, runs the main job on a generated sample
#   make test   installs dependencies, builds, runs the whole test suite
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
BUILD_TYPE ?= Release
DEMO_DIR ?= demo-out

.PHONY: all deps configure build test demo clean

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

clean:
	rm -rf $(BUILD) $(DEMO_DIR)
