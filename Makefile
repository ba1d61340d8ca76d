# roomfix: `make demo` runs the pipeline on the simulator, `make test` builds
# and runs every test. Both install missing Debian packages first.
#
#   make demo [DEMO_SECONDS=N]   the simulated pipeline for N seconds (default 30)
#             [DEMO_CAMERA=0]    ... without the ceiling camera: ultrasound alone
#   make test [SANITIZE=1]       the whole suite through ctest (ASan+UBSan build)
#   make build                   configure and build into build/
#   make spy                     lcm-spy with roomfix's types
#   make format                  clang-format every C++ file

SANITIZE ?= 0
DEMO_SECONDS ?= 30
DEMO_CAMERA ?= 1
JOBS ?= $(shell nproc)
BUILD_TYPE ?= RelWithDebInfo

ifeq ($(SANITIZE),1)
BUILD_DIR ?= build/sanitize
CMAKE_FLAGS += -DROOMFIX_SANITIZE=ON
else
BUILD_DIR ?= build
endif

.PHONY: all deps build test demo spy format clean

all: build

deps:
	@scripts/install_deps.sh

build: deps
	@cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) $(CMAKE_FLAGS) > $(BUILD_DIR).configure.log 2>&1 \
	  || { cat $(BUILD_DIR).configure.log; exit 1; }
	@cmake --build $(BUILD_DIR) -j $(JOBS) -- --no-print-directory

test: build
	@cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) --timeout 600

demo: build
	@DEMO_CAMERA=$(DEMO_CAMERA) scripts/demo.sh $(BUILD_DIR) $(DEMO_SECONDS)

spy: build
	@ROOMFIX_BUILD_DIR=$(BUILD_DIR) scripts/spy

format:
	@git ls-files '*.cc' '*.h' | xargs clang-format -i

clean:
	rm -rf build
