# Shared helpers of the end-to-end tests (sourced).
set -euo pipefail

# Drops the named columns from a CSV file (by header name).
drop_columns() {
  local file=$1; shift
  awk -F, -v drop="$*" 'BEGIN{OFS=","; n=split(drop, d, " "); for(i=1;i<=n;i++) skip[d[i]]=1}
    NR==1{for(i=1;i<=NF;i++) if($i in skip) gone[i]=1}
    {out=""; first=1; for(i=1;i<=NF;i++) if(!(i in gone)){out=out (first?"":",") $i; first=0}; print out}' "$file"
}

# Two run directories hold the same results: archive byte for byte, metrics and training logs
# except their wall-clock columns.
same_results() {
  local a=$1 b=$2
  cmp "$a/archive.csv" "$b/archive.csv" || { echo "archive.csv differs between $a and $b"; return 1; }
  diff <(drop_columns "$a/metrics.csv" wall_seconds train_seconds) <(drop_columns "$b/metrics.csv" wall_seconds train_seconds) \
    || { echo "metrics.csv differs between $a and $b"; return 1; }
  diff <(drop_columns "$a/training.csv" seconds) <(drop_columns "$b/training.csv" seconds) \
    || { echo "training.csv differs between $a and $b"; return 1; }
  for f in "$a"/*.csv; do
    name=$(basename "$f")
    case $name in archive.csv|metrics.csv|training.csv) continue ;; esac
    cmp "$f" "$b/$name" || { echo "$name differs between $a and $b"; return 1; }
  done
}

# The single seed-* run directory under OUT/NAME.
run_dir() { ls -d "$1"/*/seed-* | head -n 1; }

# mpirun for local tests: root allowed, more ranks than cores, all traffic on loopback, and none of
# mpirun's own help boxes (-q), so qdrun's one-line messages are what stderr shows.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 \
       OMPI_MCA_btl_tcp_if_include=lo OMPI_MCA_oob_tcp_if_include=lo
mpi() { local n=$1; shift; mpirun -q -np "$n" "$@" < /dev/null; }

# Under AddressSanitizer (scripts/test.sh --sanitize), OpenMPI's start-up allocations only match
# the suppressions in tests/lsan-openmpi.supp with full stacks, and with its components kept loaded
# so their frames resolve. Called by the MPI tests only: slow unwinding would slow down the rest.
mpi_sanitizer_env() {
  if [ -n "${ASAN_OPTIONS:-}" ]; then
    export ASAN_OPTIONS="$ASAN_OPTIONS:fast_unwind_on_malloc=0" OMPI_MCA_mca_base_component_disable_dlclose=1
  fi
}

# Waits until FILE exists while PID runs; fails if PID ends first (the run was too short to test).
wait_for_file() {
  local file=$1 pid=$2
  while [ ! -e "$file" ]; do
    kill -0 "$pid" 2> /dev/null || { echo "the run ended before $file appeared"; return 1; }
    sleep 0.01
  done
}

# The pid of MPI rank RANK among the children of mpirun MPIRUN_PID (a local job).
rank_pid() {
  local mpirun_pid=$1 rank=$2 c
  for c in $(pgrep -P "$mpirun_pid"); do
    # grep reads all (no -q): an early exit would SIGPIPE tr, and pipefail would read a match as none.
    tr '\0' '\n' < "/proc/$c/environ" 2> /dev/null | grep -x "OMPI_COMM_WORLD_RANK=$rank" > /dev/null &&
      { echo "$c"; return 0; }
  done
  return 1
}

# A failed run: exit code, a one-line error matching REGEX, status "failed", checkpoint present.
expect_failed_run() {
  local got=$1 want=$2 err=$3 regex=$4 dir=$5
  [ "$got" -eq "$want" ] || { echo "exit code $got, expected $want; stderr: $(cat "$err")"; return 1; }
  grep -Eq -- "$regex" "$err" || { echo "stderr does not match /$regex/: $(cat "$err")"; return 1; }
  [ "$(grep -c . "$err")" -eq 1 ] || { echo "expected a one-line error, got: $(cat "$err")"; return 1; }
  grep -q '^failed: ' "$dir/status" || { echo "status is not failed: $(cat "$dir/status")"; return 1; }
  [ -e "$dir/checkpoint.bin" ] || { echo "no checkpoint left in $dir"; return 1; }
  [ ! -e "$dir/archive.csv" ] || { echo "a failed run must not look complete"; return 1; }
}
