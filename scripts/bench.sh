#!/usr/bin/env bash
# Benchmarks (never part of the tests). Builds Release in build/ and prints one line per
# measurement. Run on a quiet machine; every ratio is measured within one process run.
#   scripts/bench.sh            framework overhead and environment throughput
#   scripts/bench.sh parallel   threads vs processes vs MPI ranks (scripts/bench-parallel.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = parallel ]; then
  shift
  exec scripts/bench-parallel.sh "$@"
fi
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DQD_BUILD_BENCHMARKS=ON -DQD_ONLY_DIRS= -DQD_EXCLUDE_DIRS= > /dev/null
cmake --build build --parallel > /dev/null
fo=build/bin/qd_framework_overhead
echo "# machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores"
echo "# framework overhead, analytic arm, 32x32 policy, MAPE-Iso, 1 worker (issue 2)"
for steps in 50 500; do
  $fo experiments/quickstart.toml --set environment.steps=$steps --set experiment.loops=3 --set experiment.iterations=100
done
echo "# environments: ps-uniform through qdrun vs a bare rollout loop, 1 and 2 workers (issue 3)"
for env in striker striker-mix-scale bipedal-walker bipedal-walker-mix-scale bipedal-kicker bipedal-kicker-mix-scale; do
  loops=4
  case $env in bipedal-*) loops=2 ;; esac
  for w in 1 2; do
    $fo experiments/$env/ps-uniform.toml --workers $w --set experiment.loops=$loops
  done
done
