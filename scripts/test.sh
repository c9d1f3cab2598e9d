#!/usr/bin/env bash
# One command: install the dependencies, build everything with warnings as errors, run the tests.
#   scripts/test.sh              Release build in build-test/
#   scripts/test.sh --sanitize   ASan + UBSan build in build-asan/
# Both build the MPI backend and run its tests (mpirun on loopback); a plain `cmake -S . -B b` builds
# without MPI.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh --mpi --plots  # OpenMPI for the MPI backend, matplotlib for qdplot
dir=build-test
flags=(-DCMAKE_BUILD_TYPE=Release -DQD_WITH_MPI=ON)
if [ "${1:-}" = "--sanitize" ]; then
  dir=build-asan
  # -O1 -g1: sanitizer reports keep function names and lines, and the build stays affordable on 2 cores.
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DQD_SANITIZE=ON -DQD_BUILD_BENCHMARKS=OFF
         -DQD_WITH_MPI=ON)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # OpenMPI keeps some start-up allocations until exit; they are not ours.
  export LSAN_OPTIONS=suppressions=$PWD/tests/lsan-openmpi.supp
fi
cmake -S . -B "$dir" -G Ninja -DQD_WERROR=ON "${flags[@]}" > /dev/null
cmake --build "$dir" --parallel
cd "$dir"
ctest --output-on-failure --no-tests=error --parallel "$(nproc)" --timeout 900
