# Thin wrapper over CMake. `make demo` and `make test` work on a fresh Debian 12 machine.
BUILD ?= build
JOBS  ?= $(shell nproc)
CLI   := $(BUILD)/bin/csympnet

.PHONY: all deps build test demo bench format clean

all: build

deps:
	@bash scripts/install-deps.sh

build: deps
	@cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release >/dev/null
	@cmake --build $(BUILD) -j $(JOBS)

test: build
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The quick reproduction: Tables 2-4 at seed 42 beside the paper's numbers (docs/reproduce.md).
# A rerun resumes: finished runs are cached in results/quick/runs.
demo: build
	@$(CLI) reproduce --suite quick --out results/quick

bench: build
	@$(BUILD)/bin/csympnet_bench --benchmark_min_time=0.2

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	@rm -rf $(BUILD)
