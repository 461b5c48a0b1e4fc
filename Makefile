# The two commands of the README. Everything else is plain CMake.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
# Optimised as RelWithDebInfo, without its debug information: a third less time to build on
# two cores (a debugger's build: cmake -S . -B build-debug -DCMAKE_BUILD_TYPE=Debug).
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS_RELEASE=-O2 -DNDEBUG"

.PHONY: setup build demo test bench fuzz clean

setup:
	./scripts/setup

$(BUILD_DIR)/build.ninja:
	cmake -S . -B $(BUILD_DIR) -G Ninja $(CMAKE_FLAGS)

build: setup $(BUILD_DIR)/build.ninja
	cmake --build $(BUILD_DIR) -j $(JOBS)

demo: build
	./$(BUILD_DIR)/apps/mtcal/mtcal demo

test: build
	ctest --test-dir $(BUILD_DIR) --output-on-failure -j $(JOBS)

bench: build
	./$(BUILD_DIR)/bench/mtcal_bench_ingest
	./$(BUILD_DIR)/bench/mtcal_bench_model
	./$(BUILD_DIR)/bench/mtcal_bench_gantry
	./$(BUILD_DIR)/bench/mtcal_bench_thermal
	./$(BUILD_DIR)/bench/mtcal_bench_diagnosis

# Every parser under libFuzzer (docs/fuzzing.md): a clang build with ASan and UBSan in
# $(FUZZ_DIR), then each fuzzer for FUZZ_SECONDS on a copy of its seed corpus in
# $(FUZZ_DIR)/corpus/<target>, what fails kept in $(FUZZ_DIR)/artifacts/<target>.
# `make fuzz FUZZ_TARGETS="plan_json linear_csv"` runs some of them only.
FUZZ_DIR ?= build-fuzz
FUZZ_SECONDS ?= 60
FUZZ_TARGETS ?=
FUZZ_CXX ?= clang++-16

fuzz: setup
	cmake -S . -B $(FUZZ_DIR) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=$(FUZZ_CXX) \
	  -DMTCAL_BUILD_FUZZ=ON -DMTCAL_BUILD_TESTS=OFF -DMTCAL_BUILD_BENCH=OFF
	cmake --build $(FUZZ_DIR) -j $(JOBS) --target mtcal_fuzzers
	./tests/fuzz/run_fuzzers.sh $(FUZZ_DIR) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

clean:
	rm -rf $(BUILD_DIR)
