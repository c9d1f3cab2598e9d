#!/usr/bin/env bash
# An MPI worker rank killed with SIGKILL (kill) or stopped past [evaluation] timeout_seconds (hang)
# ends a 3-rank run with a non-zero exit, a one-line message naming the rank, status "failed" and
# the last checkpoint intact; --resume with 2 ranks then equals an uninterrupted serial run.
#   mpi_fault.sh QDRUN EXP OUT kill|hang [--set ...]
source "$(dirname "$0")/lib.sh"
mpi_sanitizer_env
qdrun=$1 exp=$2 out=$3 mode=$4; shift 4
rm -rf "$out"
mkdir -p "$out"
signal=KILL regex="MPI worker rank 1 \(pid [0-9]+ on .*\) died and mpirun ended the job"
timeout=120
[ "$mode" = kill ] || { timeout=1 signal=STOP regex="MPI worker rank 1 \(pid [0-9]+ on .*\) made no progress for 1 s"; }
set +e
mpirun -q -np 3 "$qdrun" "$exp" -o "$out/faulty" -q --set evaluation.timeout_seconds=$timeout "$@" < /dev/null 2> "$out/err" &
pid=$!
set -e
while ! ls -d "$out"/faulty/*/seed-* > /dev/null 2>&1; do kill -0 $pid; sleep 0.01; done
dir=$(run_dir "$out/faulty")
wait_for_file "$dir/checkpoint.bin" $pid
victim=$(rank_pid $pid 1)
kill -$signal "$victim"
set +e
wait $pid
got=$?
set -e
[ "$got" -ne 0 ] || { echo "mpirun exited 0 after a rank was killed"; exit 1; }
expect_failed_run 1 1 "$out/err" "$regex" "$dir"
# The resumed run keeps the faulty run's settings; a 1 s silence limit would fail it on a busy machine.
mpi 2 "$qdrun" --resume "$dir" -q --set evaluation.timeout_seconds=120
grep -qx complete "$dir/status"
"$qdrun" "$exp" -o "$out/full" -q --workers 1 "$@"
same_results "$(run_dir "$out/full")" "$dir"
echo "mpi fault ($mode) ok"
