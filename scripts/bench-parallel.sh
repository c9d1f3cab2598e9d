#!/usr/bin/env bash
# Parallel evaluation benchmark (never part of the tests): evaluations/s of MAP-Elites-Iso runs of
# Striker, Bipedal-Walker and Bipedal-Kicker through qdrun with each backend and worker count, as
# the run itself measures them (evaluations / wall_seconds of metrics.csv, so MPI start-up is not
# counted). Speed-ups are against 1 worker of the same repetition. Noisy when the machine is busy:
# repeat (REPS=3) and compare ratios within one repetition.
#   scripts/bench-parallel.sh [ENV...]       default: striker bipedal-walker bipedal-kicker
# Needs a build with -DQD_WITH_MPI=ON in build/ (it configures one) and OpenMPI's mpirun.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh --mpi > /dev/null
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DQD_WITH_MPI=ON > /dev/null
cmake --build build --parallel > /dev/null
qdrun=$PWD/build/bin/qdrun
out=$(mktemp -d /tmp/qd-bench-parallel.XXXXXX)
trap 'rm -rf "$out"' EXIT
# Local runs only: mpirun as root, 3 ranks on 2 cores, traffic kept on loopback.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 \
       OMPI_MCA_btl_tcp_if_include=lo OMPI_MCA_oob_tcp_if_include=lo
envs=("$@")
[ ${#envs[@]} -gt 0 ] || envs=(striker bipedal-walker bipedal-kicker)
reps=${REPS:-1}

rate() {  # evaluations/s of the run under $1
  local m
  m=$(ls "$1"/*/seed-*/metrics.csv)
  awk -F, 'NR > 1 {e = $3; w = $10} END {printf "%.1f", e / w}' "$m"
}

echo "# machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores"
echo "# env rep backend workers evaluations_per_s speedup_vs_1"
for env in "${envs[@]}"; do
  budget=(--set experiment.loops=3 --set experiment.iterations=10)   # 2000 + 4000 evaluations
  case $env in bipedal-*) budget=(--set experiment.loops=2 --set experiment.iterations=5) ;; esac  # 3000
  for rep in $(seq 1 "$reps"); do
    base=""
    for cfg in "threads 1" "threads 2" "processes 2" "mpi 1" "mpi 2" "mpi 3"; do
      read -r backend n <<< "$cfg"
      dir=$out/$env-$rep-$backend-$n
      if [ "$backend" = mpi ]; then
        mpirun -q -np "$n" "$qdrun" "experiments/$env/iso.toml" -o "$dir" -q "${budget[@]}" < /dev/null
      else
        "$qdrun" "experiments/$env/iso.toml" -o "$dir" -q "${budget[@]}" --backend "$backend" --workers "$n"
      fi
      r=$(rate "$dir")
      [ "$n" != 1 ] || [ "$backend" = mpi ] || base=$r
      echo "$env $rep $backend $n $r $(awk -v r="$r" -v b="$base" 'BEGIN{printf "%.2f", r / b}')"
    done
  done
done
