# Thin wrapper over CMake. `make demo` and `make test` work on a fresh Debian 12 machine.
BUILD ?= build
JOBS  ?= $(shell nproc)
# LeakSanitizer needs ptrace; where that is missing (some containers) pass ASAN_OPTIONS_CI=detect_leaks=0.
ASAN_OPTIONS_CI ?= detect_leaks=1:abort_on_error=1
CLI   := $(BUILD)/bin/csympnet

# ccache, where installed, caches compiles across builds and build directories. With
# precompiled headers it caches only with these sloppiness settings (the headers precompiled
# are third-party ones, named in CMakeLists.txt, so no definition of ours can go unseen).
CCACHE_RUN := env;CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime;ccache
LAUNCHER := $(if $(shell command -v ccache 2>/dev/null),"-DCMAKE_CXX_COMPILER_LAUNCHER=$(CCACHE_RUN)" "-DCMAKE_C_COMPILER_LAUNCHER=$(CCACHE_RUN)")

.PHONY: all deps configure build build-demo build-tests test test-long test-asan fuzz fuzz-build fuzz-merge fuzz-hours demo reproduce bench docs format clean

all: build

deps:
	@bash scripts/install-deps.sh

configure: deps
	@cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release $(LAUNCHER) >/dev/null

# Everything: the library, the CLI, the Python module, the test programs and the benchmarks.
build: configure
	@cmake --build $(BUILD) -j $(JOBS)

# What `make demo` runs and nothing else: the CLI and the Python module (CMake target
# csympnet_programs), not the test programs or the benchmarks.
build-demo: configure
	@cmake --build $(BUILD) -j $(JOBS) --target csympnet_programs

# The suite but its long tests (label `long`, tests/long_tests.txt: coverage studies, whole
# fits on large records, the benchmark's smoke runs, pip and the documentation site); `make
# test-long` runs those, and CI runs both.
test: build-tests
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -LE long

test-long: build-tests
	@cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L long

# What the tests run (CMake target csympnet_test_programs): everything but the benchmarks.
build-tests: configure
	@cmake --build $(BUILD) -j $(JOBS) --target csympnet_test_programs

# The documentation site: the guide (docs/*.md) and the Python API reference, in
# $(BUILD)/docs/html (open index.html).
docs: build-demo
	@PYTHONPATH=$(BUILD)/python /usr/bin/python3 -m sphinx -q -b html -d $(BUILD)/docs/doctrees docs $(BUILD)/docs/html
	@echo "docs: $(BUILD)/docs/html/index.html"

# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer, in $(ASAN_BUILD), compiled
# by clang 14 (ASAN_CC, ASAN_CXX; scripts/install-deps.sh installs it with its sanitizer
# runtimes): its build took 660 s where gcc 12's took 906 s, the same suite passing under both
# (docs/testing.md, "The sanitizer build"). At -O1 with line tables only (-g1): 35-51% less
# compile CPU than -O2 -g on the heaviest files, and stack traces still name file and line.
# The long tests (label `long`) are left out: their stages run in the other tests, under the
# sanitizers too. ASAN_EXCLUDE (a ctest -E regex, empty by default) leaves out more if CI time
# needs it; docs/hardening.md says which are pure numerics covered by `make test`.
ASAN_BUILD   ?= build-asan
ASAN_EXCLUDE ?=
ASAN_CC      ?= clang-14
ASAN_CXX     ?= clang++-14
test-asan: deps
	@cmake -S . -B $(ASAN_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCSYMPNET_SANITIZE=ON \
	  -DCMAKE_C_COMPILER=$(ASAN_CC) -DCMAKE_CXX_COMPILER=$(ASAN_CXX) \
	  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
	  -DCSYMPNET_BUILD_PYTHON=OFF -DCSYMPNET_BUILD_BENCH=OFF $(LAUNCHER) >/dev/null
	@cmake --build $(ASAN_BUILD) -j $(JOBS)
	@cd $(ASAN_BUILD) && ASAN_OPTIONS=$(ASAN_OPTIONS_CI) UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  ctest --output-on-failure -j $(JOBS) -LE long $(if $(ASAN_EXCLUDE),-E '$(ASAN_EXCLUDE)')

# libFuzzer targets (clang-14 from Debian), FUZZ_SECONDS per target; the time spent is
# appended to fuzz/hours.md. Crashes are kept in fuzz/regressions/, which `make test` replays.
FUZZ_BUILD   ?= build-fuzz
FUZZ_SECONDS ?= 60
FUZZ_TARGETS := fuzz_csv_pairs fuzz_csv_trajectories fuzz_model_file fuzz_cli_args fuzz_suite_file
fuzz-build:
	@CC=clang-14 CXX=clang++-14 cmake -S . -B $(FUZZ_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCSYMPNET_FUZZ=ON -DCSYMPNET_SANITIZE=ON -DCSYMPNET_BUILD_PYTHON=OFF \
	  -DCSYMPNET_BUILD_BENCH=OFF -DCSYMPNET_BUILD_TESTS=OFF >/dev/null
	@cmake --build $(FUZZ_BUILD) -j $(JOBS) --target $(FUZZ_TARGETS)

fuzz: fuzz-build
	@bash fuzz/run.sh $(FUZZ_BUILD) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

# Minimises each working corpus (libFuzzer -merge=1) back into the checked-in fuzz/corpus.
fuzz-merge: fuzz-build
	@for t in $(FUZZ_TARGETS); do \
	  rm -rf $(FUZZ_BUILD)/merged/$$t && mkdir -p $(FUZZ_BUILD)/merged/$$t $(FUZZ_BUILD)/corpus/$$t && \
	  $(FUZZ_BUILD)/bin/$$t -merge=1 -max_len=32768 $(FUZZ_BUILD)/merged/$$t fuzz/corpus/$$t \
	    $(FUZZ_BUILD)/corpus/$$t 2>/dev/null && \
	  rm -f fuzz/corpus/$$t/* && cp $(FUZZ_BUILD)/merged/$$t/* fuzz/corpus/$$t/ && \
	  echo "$$t: $$(ls fuzz/corpus/$$t | wc -l) files"; done

fuzz-hours:
	@awk -F'|' '$$5 ~ /^ *[0-9]+ *$$/ {s += $$5} END {printf "fuzzed %.0f CPU s = %.2f CPU hours\n", s, s / 3600}' fuzz/hours.md

# What a user does first, on a record shaped like a user's (examples/pendulum_record.csv: a
# damped pendulum in degrees, with its own column names): fit it (γ̂ with its interval, and
# the figure results/demo-fit/fit.png: the record against the model's free run, the
# residuals, the amplitude decay, the modes); then a held-out forecast: fit the first 45 s and
# run the model freely over the last 15 s, scored against the record (results/demo-forecast).
DEMO_COLUMNS := --columns t=time_s,q1=angle_deg,p1=angular_velocity_deg_s
DEMO_FIT := $(CLI) fit examples/pendulum_record.csv $(DEMO_COLUMNS) --out results/demo-fit --force -q
DEMO_DIR := results/demo-forecast
demo: build-demo
	@echo "== 1. csympnet fit on examples/pendulum_record.csv (true gamma 0.12 1/s) =="
	@echo "$(DEMO_FIT)" | tr -s ' '
	@$(DEMO_FIT)
	@test ! -e results/demo-fit/fit.png || echo "figure: results/demo-fit/fit.png and fit.pdf"
	@echo "== 2. forecast: fit the first 45 s, run the model freely over the last 15 s =="
	@mkdir -p $(DEMO_DIR)
	@awk -F, 'NR == 1 || $$1 <= 45' examples/pendulum_record.csv > $(DEMO_DIR)/first45.csv
	@awk -F, 'NR == 1 || $$1 > 45' examples/pendulum_record.csv > $(DEMO_DIR)/last15.csv
	@$(CLI) fit $(DEMO_DIR)/first45.csv $(DEMO_COLUMNS) --out $(DEMO_DIR)/fit --force -q --no-figures | sed -n '1s/^/first 45 s: /p'
	@$(CLI) evaluate --model $(DEMO_DIR)/fit/model.json --data $(DEMO_DIR)/last15.csv $(DEMO_COLUMNS) \
	  --out $(DEMO_DIR)/evaluate --force >/dev/null
	@/usr/bin/python3 -c 'import json; o = json.load(open("$(DEMO_DIR)/evaluate/report.json"))["observed"]; \
	  print("forecast of the last %.1f s from the state at 45 s: rollout NRMSE %.3g, within 10%% of the spread for %.1f s" \
	  % (o["per_trajectory"][0]["span"], o["rollout_nrmse"], o["valid_time_mean"]))'
	@PYTHONPATH=$(BUILD)/python /usr/bin/python3 -m csympnet.fit_figure $(DEMO_DIR)/fit \
	  --data $(DEMO_DIR)/last15.csv --path $(DEMO_DIR)/forecast \
	  && echo "figure: $(DEMO_DIR)/forecast.png and forecast.pdf (the last 15 s against the forecast)" \
	  || echo "forecast figure not drawn (python3 with matplotlib and the module in $(BUILD)/python)"

# The quick reproduction: Tables 2-4 at seed 42 beside the paper's numbers (docs/reproduce.md).
# A rerun resumes: finished runs are cached in results/quick/runs.
reproduce: build-demo
	@echo "== csympnet reproduce --suite quick: Tables 2-4 beside the paper =="
	@$(CLI) reproduce --suite quick --out results/quick

# One table, measured in one run: ms per training epoch, csympnet vs PyTorch (float64, same
# model, data and AdamW) on 1 and 2 threads each, FLOPs, FLOP rate against dgemm, peak memory
# (docs/benchmarks.md). Installs python3-torch if missing. BENCH_ARGS passes options, e.g.
# BENCH_ARGS="--threads 1 --presets s1,s2". The micro-benchmarks alone: $(BUILD)/bin/csympnet_bench.
bench: build
	@bash scripts/install-deps.sh --bench
	@/usr/bin/python3 bench/bench_table.py --build $(BUILD) $(BENCH_ARGS)

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	@rm -rf $(BUILD)
