#!/usr/bin/env bash
# One command: install the dependencies, build everything with warnings as errors, run the tests.
#   scripts/test.sh              Release build in build-test/
#   scripts/test.sh --sanitize   ASan + UBSan build in build-asan/
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh --plots  # matplotlib for the qdplot tests
dir=build-test
flags=(-DCMAKE_BUILD_TYPE=Release)
if [ "${1:-}" = "--sanitize" ]; then
  dir=build-asan
  # -O1 -g1: sanitizer reports keep function names and lines, and the build stays affordable on 2 cores.
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DQD_SANITIZE=ON -DQD_BUILD_BENCHMARKS=OFF)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
fi
cmake -S . -B "$dir" -G Ninja -DQD_WERROR=ON "${flags[@]}" > /dev/null
cmake --build "$dir" --parallel
cd "$dir"
ctest --output-on-failure --no-tests=error --parallel "$(nproc)" --timeout 900
