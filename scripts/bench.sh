#!/usr/bin/env bash
# Benchmarks (never part of the tests). Builds Release in build/ and prints one line per
# measurement. Every ratio is measured within one process: the bare loop's batches run between
# the qdrun run's iterations, so both sides see the same machine speed (a shared VM drifts by tens
# of per cent within seconds), and the median over --repeat runs is printed
# (qd_framework_overhead --whole alternates whole bare loops and whole runs instead and compares
# the fastest of each side). Run on a quiet machine; `nice -n -10 scripts/bench.sh` helps.
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
echo "# the paper's workloads: qdrun vs a bare rollout loop with the same environment object, 1 and 2 workers,"
echo "#   and 1 worker in-process (backend=threads) beside the default supervised worker process (backend=auto)"
echo "#   ps-uniform: the bare loop rolls out the very same policies, so the ratio is the framework alone"
echo "#   MAPE-Iso: qdrun also pays the plugin's mutation"
for env in striker striker-mix-scale bipedal-walker bipedal-walker-mix-scale bipedal-kicker bipedal-kicker-mix-scale; do
  loops=51                    # 102 000 evaluations
  case $env in bipedal-*) loops=6 ;; esac   # 12 000 evaluations
  for w in 1 2; do
    $fo experiments/$env/ps-uniform.toml --workers $w --repeat 2 --set experiment.loops=$loops
  done
  # the default above runs one supervised worker process; this is the unsupervised in-process mode
  $fo experiments/$env/ps-uniform.toml --workers 1 --repeat 2 --set experiment.loops=$loops --set evaluation.backend=threads
done
for env in striker bipedal-walker; do
  loops=11
  case $env in bipedal-*) loops=3 ;; esac
  $fo experiments/$env/iso.toml --workers 1 --repeat 2 --set experiment.loops=$loops
done
echo "# the framework's floor: analytic arm (12 us episodes), 32x32 policy (1379 parameters), 1 worker"
for exp in arm-uniform arm-iso; do
  $fo bench/experiments/$exp.toml --repeat 5                                              # 1 002 000 evaluations, 50 steps
done
echo "# autoencoder training (plugins/autoencoder/bench)"
build/bin/autoencoder_bench
