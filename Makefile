# roomfix: `make demo` runs the pipeline on the simulator, `make test` builds
# and runs every test. Both install missing Debian packages first: `make demo`
# only the demo's (scripts/install_deps.sh demo), the others all of them.
#
#   make demo [DEMO_SECONDS=N]   builds only the demo's programs, then runs the
#                                simulated pipeline for N seconds (default 30);
#                                a new build folder is configured without tests
#                                and Java, an existing one keeps its settings
#             [DEMO_CAMERA=0]    ... without the ceiling camera: ultrasound alone
#             [DEMO_SITE=FILE]   ... another site, e.g. config/sites/hall.yaml
#                                (four cameras, two radios, eight robots)
#             [DEMO_CAMERA_FPS=N] ... cameras at N fps (default: the site's,
#                                10 with fewer than 2 cores per camera)
#             [DEMO_DEVICES=firmware] ... the beacon and the receivers as their
#                                firmware in simavr (docs/firmware_in_the_loop.md)
#   make test [SANITIZE=1]       the whole suite through ctest (ASan+UBSan build);
#                                turns the tests and the Java jar on in the
#                                build folder
#   make build                   configure and build everything into build/
#   make package                 a Release build in build/release and its
#                                Debian package build/release/roomfix_<version>_<arch>.deb
#   make spy                     lcm-spy with roomfix's types
#   make format                  clang-format every C++ file
#   CMAKE_ARGS="-D..."           more arguments for CMake's configure step, for
#                                any target (-DROOMFIX_VIEWER_WINDOW=OFF, ...)
#
# Warnings are errors (ROOMFIX_WERROR=ON) in every build folder these targets
# configure, from the first: `make demo` then `make test` compile each file
# once, since a flag that changes between them would rebuild every file.
# WERROR=0 makes them warnings (a compiler other than Debian 12's GCC 12 or
# clang 14 may warn where those do not); a plain `cmake` keeps them warnings.

SANITIZE ?= 0
WERROR ?= 1
DEMO_SECONDS ?= 30
DEMO_CAMERA ?= 1
DEMO_DEVICES ?= behavioural
JOBS ?= $(shell nproc)
BUILD_TYPE ?= RelWithDebInfo
RELEASE_DIR ?= build/release

ifeq ($(SANITIZE),1)
BUILD_DIR ?= build/sanitize
CMAKE_FLAGS += -DROOMFIX_SANITIZE=ON
else
BUILD_DIR ?= build
endif
WERROR_FLAG = -DROOMFIX_WERROR=$(if $(filter 1 ON on,$(WERROR)),ON,OFF)
# Said when a build fails with warnings as errors.
WERROR_HINT = { echo "make: the build failed. If on a warning: make's builds treat warnings as errors; WERROR=0 makes them warnings (for a compiler other than Debian 12's GCC 12 or clang 14)." >&2; exit 1; }
# The Debian packages to install (scripts/install_deps.sh): all, or demo.
DEPS_SET = all

.PHONY: all deps configure configure-demo configure-test build test demo package spy format clean

all: build

deps:
	@scripts/install_deps.sh $(DEPS_SET)

configure: deps
	@mkdir -p $(dir $(BUILD_DIR))
	@cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) $(CMAKE_FLAGS) $(WERROR_FLAG) $(CMAKE_ARGS) \
	  > $(BUILD_DIR).configure.log 2>&1 || { cat $(BUILD_DIR).configure.log; exit 1; }

build: configure
	@cmake --build $(BUILD_DIR) -j $(JOBS) -- --no-print-directory || $(WERROR_HINT)

# The build folder's settings for `make test` and `make demo` (also run alone
# by tests/build/one_build_test.sh, which checks that the second compiles
# nothing the first built).
configure-test: CMAKE_FLAGS += -DBUILD_TESTING=ON -DROOMFIX_JAVA=ON
configure-test: configure

test: configure-test
	@cmake --build $(BUILD_DIR) -j $(JOBS) -- --no-print-directory || $(WERROR_HINT)
	@cd $(BUILD_DIR) && $(if $(filter 1,$(SANITIZE)),LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan_suppressions.txt) \
	  ctest --output-on-failure -j $(JOBS) --timeout 600

# Only what scripts/demo.sh runs: no test, no GoogleTest, no Java. The
# packages of the demo only; a build folder without a CMake cache yet is
# configured with the tests and the jar off (their packages may be absent); one
# that has a cache (after `make test`, say) keeps its settings, so nothing is
# rebuilt.
configure-demo: DEPS_SET = demo$(if $(filter firmware,$(DEMO_DEVICES)), firmware)
configure-demo: CMAKE_FLAGS += $(if $(wildcard $(BUILD_DIR)/CMakeCache.txt),,-DBUILD_TESTING=OFF -DROOMFIX_JAVA=OFF)
configure-demo: configure

demo: configure-demo
	@cmake --build $(BUILD_DIR) -j $(JOBS) --target demo -- --no-print-directory || $(WERROR_HINT)
	@if [ "$(DEMO_DEVICES)" = firmware ]; then \
	  cmake --build $(BUILD_DIR) -j $(JOBS) --target firmware -- --no-print-directory; fi
	@DEMO_CAMERA=$(DEMO_CAMERA) DEMO_SITE=$(DEMO_SITE) DEMO_CAMERA_FPS=$(DEMO_CAMERA_FPS) \
	  DEMO_DEVICES=$(DEMO_DEVICES) scripts/demo.sh $(BUILD_DIR) $(DEMO_SECONDS)

package: BUILD_DIR = $(RELEASE_DIR)
package: BUILD_TYPE = Release
package: build
	@cd $(RELEASE_DIR) && cpack -G DEB

spy: build
	@ROOMFIX_BUILD_DIR=$(BUILD_DIR) scripts/spy

format:
	@git ls-files '*.cc' '*.h' | xargs clang-format -i

clean:
	rm -rf build
