# crease: a thin front over CMake. `make run` and `make check` are the README's two commands.
JOBS    ?= $(shell nproc)
PEERS   ?= sim,nn
RELEASE := build/release
ASAN    := build/sanitize
FUZZ    := build/fuzz
OPT     := build/opt
CLANG   := build/clang
# Warnings are errors in every build made here (CMake's default is off, for packagers).
WERROR  := -DCREASE_WERROR=ON
OUT     ?= out
FUZZ_SMOKE_S ?= 10
FUZZ_LONG_S  ?= 300
PREFIX  ?= /usr/local

.PHONY: all deps build run check test test-long test-asan build-opt test-clang fuzz-build fuzz-smoke \
        fuzz bench bench-peers install clean

all: build

deps:
	@bash scripts/deps.sh

$(RELEASE)/CMakeCache.txt:
	cmake -S . -B $(RELEASE) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_INSTALL_PREFIX=$(PREFIX) \
	      $(WERROR) >/dev/null

build: deps $(RELEASE)/CMakeCache.txt
	cmake --build $(RELEASE) -j $(JOBS)

# The main job on built-in defaults.
run: build
	@bash scripts/run_demo.sh $(RELEASE)/crease $(OUT)

test: build
	cd $(RELEASE) && ctest --output-on-failure -j $(JOBS) -LE long

# The acceptance runs of minutes (ctest label "long") and the 1,500-frame
# stability run of a 10k-vertex tube on a swinging collider.
test-long: build
	cd $(RELEASE) && ctest --output-on-failure -L long
	$(RELEASE)/bench_sim tube10k 2 1500

# The sanitizer stage is built with clang (ASan + UBSan, libomp), so it is also the
# second compiler's stage: its warnings, its code generation and its OpenMP runtime on
# every test; one stage instead of a clang one and a gcc sanitizer one (make check went
# from about 23 to about 18 minutes on 2 cores, docs/ARCHITECTURE.md). -O2 rather than
# -O1: the sanitizer stage is the longest. The tests run quick (CMakeLists.txt) and on one
# OpenMP thread each, two tests at a time: under the sanitizers a second thread bought
# epnet's tests 2 % of wall time for twice the CPU. The release stage runs every test on
# the machine's threads, and cli_dataset_repro asks for two threads here as well.
test-asan: deps
	CC=clang cmake -S . -B $(ASAN) -DCMAKE_BUILD_TYPE=Debug -DCREASE_SANITIZE=ON \
	      -DCREASE_TEST_QUICK=ON $(WERROR) -DCMAKE_C_FLAGS_DEBUG="-O2 -g" >/dev/null
	cmake --build $(ASAN) -j $(JOBS)
	cd $(ASAN) && OMP_NUM_THREADS=1 ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
	      ctest --output-on-failure -j $(JOBS) -LE long

$(FUZZ)/CMakeCache.txt:
	CC=clang cmake -S . -B $(FUZZ) -DCMAKE_BUILD_TYPE=Debug -DCREASE_FUZZ=ON -DCREASE_OPENMP=OFF $(WERROR) \
	      -DCMAKE_C_FLAGS="-O1 -g -fsanitize=address,undefined -fsanitize=fuzzer-no-link" \
	      -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null

# CMake's Release type (-O3 -DNDEBUG) as a packager builds it, so that build cannot break
# unseen: compiled (library, tool, tests, benchmarks, examples), not run.
$(OPT)/CMakeCache.txt:
	cmake -S . -B $(OPT) -DCMAKE_BUILD_TYPE=Release $(WERROR) >/dev/null

build-opt: deps $(OPT)/CMakeCache.txt
	cmake --build $(OPT) -j $(JOBS)

# clang's Release type (-O3) with its tests, quick: not in `make check`, whose sanitizer
# stage is clang's; for a look at clang's optimiser at -O3.
$(CLANG)/CMakeCache.txt:
	CC=clang cmake -S . -B $(CLANG) -DCMAKE_BUILD_TYPE=Release -DCREASE_TEST_QUICK=ON $(WERROR) \
	      >/dev/null

test-clang: deps $(CLANG)/CMakeCache.txt
	cmake --build $(CLANG) -j $(JOBS)
	cd $(CLANG) && ctest --output-on-failure -j $(JOBS) -LE long

fuzz-build: deps $(FUZZ)/CMakeCache.txt
	cmake --build $(FUZZ) -j $(JOBS) --target fuzzers

fuzz-smoke: fuzz-build
	@bash scripts/fuzz.sh $(FUZZ) $(FUZZ_SMOKE_S)

fuzz: fuzz-build
	@bash scripts/fuzz.sh $(FUZZ) $(FUZZ_LONG_S)

check: test build-opt test-asan fuzz-smoke
	@echo "check: all tests passed (release, Release -O3 build, clang with sanitizers, fuzz smoke)"

bench: build
	@for b in $(RELEASE)/bench_*; do echo "== $$b"; $$b || exit 1; done

# Side by side with Blender's cloth solver and PyTorch (installs Debian's blender and
# python3-torch there only; never in `make check`); PEERS=sim or PEERS=nn for one part.
bench-peers: build
	@bash scripts/bench_peers.sh $(RELEASE)/crease $(RELEASE)/bench_peers $(PEERS)

install: build
	cmake --install $(RELEASE) --prefix $(PREFIX)

clean:
	rm -rf build

# Dataset and fit throughput at 1 and 2 MPI ranks, and the expected scaling (docs/mpi.md).
.PHONY: bench-mpi
bench-mpi: build
	@bash bench/bench_mpi.sh $(RELEASE)/crease
