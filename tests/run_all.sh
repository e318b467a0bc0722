#!/usr/bin/env bash
# Builds and runs every test: a Release build with warnings as errors (unit, UI screenshot and
# command-line tests), the Debian package (built, installed, used and removed: packaging/check-package.sh,
# as root or with sudo), the unit tests under AddressSanitizer + UndefinedBehaviorSanitizer, and the
# worker tests under ThreadSanitizer. Run from anywhere; needs packaging/install-deps.sh first.
set -euo pipefail
cd "$(dirname "$0")/.."

jobs=$(nproc)
# Unity builds (CMake's default batches of 8 sources per translation unit): each batch parses the
# shared headers (Eigen, OpenCV, spdlog, GoogleTest) and instantiates their templates once instead
# of once per file. Sources keep their file-local helpers apart by name, so they compile alone
# (what a developer's build does) and batched alike; see README's clean-CI-run row for figures.
# Ninja rather than Make: Make's per-target makefiles start compiling a target's sources only after
# the libraries it links are built, so the second core idled while the core library's last batch
# compiled (44 s of 569 in the ASan stage's build, 2026-12-03); Ninja orders only the links. A
# tree configured earlier with another generator keeps it (CMake refuses to switch).
# GCC's garbage collector runs each time its heap has doubled since the last collection, from
# 128 MB on (`g++ -Q --help=params`: ggc-min-expand 100, ggc-min-heapsize 131072 kB); a batch of
# this code base instantiates 1-4 GB of Eigen and OpenCV templates, and collecting all along cost
# 9-12 % of the compile (the core batch with the photometric back end: 76 -> 67 s in Release,
# 139 -> 124 s with the sanitizers, peak 3.0 -> 3.9 GB a compile, 2026-12-06). With two compiles
# at a time that stays far inside the 24 GiB the brief's machine has.
gcc_heap=()
if "${CXX:-c++}" -v 2>&1 | grep -q '^gcc version'; then
  gcc_heap=("-DCMAKE_CXX_FLAGS=--param=ggc-min-expand=1000 --param=ggc-min-heapsize=8388608")
fi
configure() {  # configure DIR [cmake args...]
  local dir=$1; shift
  local generator=(-G Ninja)
  if [ -f "$dir/CMakeCache.txt" ] && ! grep -q '^CMAKE_GENERATOR:INTERNAL=Ninja$' "$dir/CMakeCache.txt"; then
    generator=()
  fi
  cmake "${generator[@]}" -S . -B "$dir" -DNIRSLAM_WERROR=ON -DCMAKE_UNITY_BUILD=ON "${gcc_heap[@]}" "$@" > "$dir.configure.log" 2>&1 ||
    { cat "$dir.configure.log"; return 1; }
}
section() { printf '\n=== %s (%s, %d s in) ===\n' "$*" "$(date +%T)" "$SECONDS"; }  # times: CI must stay under 30 min

section "Release build"
mkdir -p build
configure build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$jobs"
section "Release: all tests"
ctest --test-dir build --output-on-failure -j"$jobs"

section "Debian package: build, install, run from outside the source tree, remove"
packaging/check-package.sh build

section "AddressSanitizer + UndefinedBehaviorSanitizer: build"
# -Og rather than the -O1 the AddressSanitizer documentation suggests: the build took a third less
# (421 against 673 s of wall, 755 against 1213 s of CPU; -O1's inlining and scalar replacement of
# Eigen's small matrices were most of it) for tests 36 % slower (147 against 108 s of CPU),
# 2026-12-06; both run several times faster than at -O0 (60 against about 400 s of wall,
# 2026-12-02). Code compiled unlike the Release stage's also shows what one optimiser hides: -Og
# found a test reading an uninitialised Eigen vector. GCC 12 gives a false -Wmaybe-uninitialized
# inside std::variant when optimising (tests/worker/test_worker.cpp), so this stage alone leaves
# that warning out; the Release stage keeps it. -g1 (line tables, function names: what sanitizer
# reports print) instead of -g.
# Four of UndefinedBehaviorSanitizer's checks are left out here, which together cost 30 % of
# photometric_backend.cpp's compile (35 against 50 s) and 8 % of the core library's (613 against
# 669 s of CPU; with Ninja too, this stage's build 493 against 569 s of wall, 2026-12-03), and
# each is covered otherwise: null (a null dereference is a
# SEGV that AddressSanitizer reports with its stack), pointer-overflow (an out-of-range pointer
# is caught by AddressSanitizer when it is dereferenced), alignment (x86 loads unaligned data;
# Eigen asserts its own fixed-size alignment in this assert-enabled build) and vptr (the core
# has a handful of interfaces, no downcasts). Signed overflow, shifts, bounds, division by zero,
# invalid bool / enum values, missing returns and unreachable code are still checked.
configure build-asan -DCMAKE_BUILD_TYPE=Debug -DNIRSLAM_SANITIZE=address,undefined -DNIRSLAM_BUILD_UI=OFF \
  "-DCMAKE_CXX_FLAGS_DEBUG=-Og -g1 -Wno-maybe-uninitialized -fno-sanitize=null,pointer-overflow,alignment,vptr" \
  "-DCMAKE_C_FLAGS_DEBUG=-Og -g1 -fno-sanitize=null,pointer-overflow,alignment,vptr" \
  -DNIRSLAM_TEST_SHARDS=4 -DNIRSLAM_WHOLE_SEQUENCE_TESTS=OFF
cmake --build build-asan -j"$jobs" --target nirslam_core_tests nirslam_worker_tests
section "AddressSanitizer + UndefinedBehaviorSanitizer: unit tests"
# Each test binary runs as four GoogleTest shards (ctest entries) rather than one process per test:
# an ASan process spends about half a second loading its ~150 shared libraries, and 406 of them
# made this stage 169-214 s of wall; as shards it is about 40 s. Four rather than two: GoogleTest
# deals the tests out in turn, and the shard with the longest test (the geometric start's replay,
# about a third of the core tests' time) ran 73 s while the other ran 29 (2026-12-05). Every test
# still runs in its own process in the Release stage. A failing shard prints its whole log; the
# failing test's name is in it ("[  FAILED  ]").
# Whole simulated sequences (tests/core/whole_sequence/: the accuracy tables, the odometry's and
# the pipeline's sequences, the simulated wall approaches of the lamp factor, whose residuals and
# Jacobians have unit tests that stay) are left to the Release run and out of this build: a Debug
# build with sanitisers is 20-50x slower on them and they exercise no code the unit tests do not.
# Tests in the unit-test files left to the Release run as well: the two whole-pipeline worker
# tests (3 and 2 minutes here; ThreadSanitizer runs them too), the lamp offset found from
# rendered frames (the estimator's own tests on synthetic points stay), the initialiser's
# two-thread check on a simulated sequence (7 minutes here) and the corrected frames following
# the estimate over 400 frames (3 minutes; ThreadSanitizer runs it too). Also left to the
# Release run, to keep CI under 30 minutes: unit tests that took 10-35 s each here on whole
# images or real data (the Canon exposure stack, the drift check of the KLT tracker, coarse
# alignment of a rendered pair, the renderer's culling against brute force, the beam fit to the
# simulator's halo, two undistortion checks, the marginalisation prior against the full problem,
# the held geometric start on a room start from frame 30: 4 s here, 70 frames rendered at 2x2;
# the replay test with the hold on by default stays); the window optimisation's energy test stays.
# Likewise where a sibling test drives the same code through the sanitisers: the geometric start
# on rendered walls and on the lamp-lit room (36 and 28 s here; the replay test runs the same
# start inside the odometry, 67 s), the keyframe choice on a reported exposure step (20 s; the
# choice without it stays) and the held correction (10 s; the gate's rejected estimates, on the
# same frames through the same calibration, stay): this stage's tests 122 -> 80 s (2026-12-05).
release_only=(
  'ExposureEstimator.ConstantRadiance*' 'ExposureEstimator.CoLocated*' 'WorkerOnSimulator.PipelineViews*'
  'PhotometricOnlineCalibration.BackgroundBackEnd*' '*FromRendered*'
  '*ParallelHypothesesGiveTheSameResult*' '*CorrectionFollowsTheEstimate*'
  '*RealCanonStack*' '*DriftCheckDropsTracks*' '*CoarseAlignmentRecoversKnownMotion*'
  '*TileCullingFindsTheSameSurfaces*' 'BeamFromHalo.FromTheSimulatorsHaloFactor*'
  '*UndistortedImageMatchesTheIdealPinholeImage*' '*SixteenBitImagesKeepTheirRange*'
  '*MarginalisationPriorGivesTheFullProblemsStep*' '*HeldKeyframesKeepTheDirection*'
  'GeometricStart.TooLittleTranslation*' 'GeometricStart.DirectionOfTheHandHeldRoom*'
  'PhotometricKeyframeChoice.AReportedExposureChange*' 'PhotometricGate.HeldCorrectionKeeps*'
)
GTEST_FILTER="-$(IFS=:; echo "${release_only[*]}")" \
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build-asan --output-on-failure -j"$jobs"

section "ThreadSanitizer: build"
# Clang rather than GCC for this stage: GCC took twice as long to compile the core under
# ThreadSanitizer (photometric_backend.cpp 44 s at -O2, 41 s at -O1, against 18 s with clang 14
# at -O1; the worker tests' build alone 267 -> 136 s of wall, in clean CI runs this stage's build
# 267 -> 148-174 s and its tests 25 -> 16-19 s, 2026-12-07), and a second
# compiler's warnings (-Werror here too) see what GCC's do not. The GCC-only heap parameters stay
# out of this configure; a tree configured with another compiler is configured afresh.
gcc_heap=()
if [ -f build-tsan/CMakeCache.txt ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++-14$' build-tsan/CMakeCache.txt; then
  rm -rf build-tsan
fi
configure build-tsan -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DNIRSLAM_SANITIZE=thread -DNIRSLAM_BUILD_UI=OFF \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
cmake --build build-tsan -j"$jobs" --target nirslam_worker_tests
section "ThreadSanitizer: worker tests"
TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/tests/tsan-suppressions.txt" \
  ctest --test-dir build-tsan --output-on-failure -j"$jobs" -L worker
section "all stages passed"
