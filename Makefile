# The two commands of the README. Everything else is plain CMake.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=RelWithDebInfo

.PHONY: setup build demo test bench clean

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

clean:
	rm -rf $(BUILD_DIR)
