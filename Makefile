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

# One table, measured in one run: ms per training epoch, csympnet vs PyTorch (float64, same
# model, data and AdamW), FLOPs, FLOP rate against dgemm, peak memory (docs/benchmarks.md).
# Needs python3-torch and libopenblas0-pthread (bench/bench_table.py says so if missing);
# BENCH_ARGS passes options, e.g. BENCH_ARGS="--threads 2". The micro-benchmarks alone:
# $(BUILD)/bin/csympnet_bench.
bench: build
	@/usr/bin/python3 bench/bench_table.py --build $(BUILD) $(BENCH_ARGS)

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	@rm -rf $(BUILD)
