# The two entry points of the README. Both install what is missing (Debian
# packages, via scripts/install-deps.sh), apply the host settings the stack
# needs (scripts/host-setup.sh: the socket receive buffer limit), configure
# and build in build/.
BUILD_DIR ?= build
BUILD_TYPE ?= Release
JOBS ?= $(shell nproc)

.PHONY: all deps configure build test demo clean asan-test fuzz install package

all: build

deps:
	bash scripts/install-deps.sh
	bash scripts/host-setup.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE)

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# The whole test suite.
test: build
	ctest --test-dir $(BUILD_DIR) --output-on-failure -j $(JOBS) --timeout 600

# The whole test suite built with AddressSanitizer and UndefinedBehaviorSanitizer
# (gcc, RelWithDebInfo) in build-asan/; any finding fails its test.
ASAN_DIR ?= build-asan
# Throughput tests (a 1080p stream at 30 frames/s through the process set
# without losing a frame) measure speed, which the sanitizers take away:
# they run in `make test`.
ASAN_SKIP ?= Stack.NoImageLoss1080p30
asan-test: deps
	cmake -S . -B $(ASAN_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLD_SANITIZE=ON
	cmake --build $(ASAN_DIR) -j $(JOBS)
	ASAN_OPTIONS=detect_leaks=1:detect_stack_use_after_return=1 \
	UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	LSAN_OPTIONS=suppressions=$(CURDIR)/tests/sanitizer/lsan.supp \
	ctest --test-dir $(ASAN_DIR) --output-on-failure -j $(JOBS) --timeout 1200 $(if $(ASAN_SKIP),-E '$(ASAN_SKIP)')

# Long fuzzing runs: FUZZ_TIME seconds per target (see scripts/fuzz.sh).
FUZZ_TIME ?= 600
fuzz: deps
	bash scripts/fuzz.sh all build-fuzz $(FUZZ_TIME)

# The main job on the embedded default (no camera needed).
demo: build
	bash scripts/demo.sh $(BUILD_DIR)

# Install the build (run `make build` first; as root for a system prefix).
PREFIX ?= /usr/local
install:
	cmake --install $(BUILD_DIR) --prefix $(PREFIX)

# The Debian packages (build/package/landmark_<version>_<arch>.deb and landmark-dev_..., /usr prefix).
package: build
	cd $(BUILD_DIR) && cpack --config CPackConfig.cmake -B package

clean:
	rm -rf $(BUILD_DIR)
