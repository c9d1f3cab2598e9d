#!/usr/bin/env bash
# A worker process killed with SIGKILL (or stopped, so it hangs past [evaluation] timeout_seconds)
# ends the run with exit code 3, a one-line message naming it, status "failed" and the last
# checkpoint intact; --resume with another worker count then equals an uninterrupted run.
#   process_fault.sh QDRUN EXP OUT kill|hang [--set ...]
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3 mode=$4; shift 4
rm -rf "$out"
mkdir -p "$out"
signal=KILL regex="worker process 1 \(pid [0-9]+\) was killed by signal 9"
timeout=120
[ "$mode" = kill ] || { timeout=1 signal=STOP regex="worker process 1 \(pid [0-9]+\) made no progress for 1 s"; }
set +e
"$qdrun" "$exp" -o "$out/faulty" -q --backend processes --workers 2 --set evaluation.timeout_seconds=$timeout "$@" 2> "$out/err" &
pid=$!
set -e
# The run directory appears at start; the checkpoint after loop 0, while later loops still run.
while ! ls -d "$out"/faulty/*/seed-* > /dev/null 2>&1; do kill -0 $pid; sleep 0.01; done
dir=$(run_dir "$out/faulty")
wait_for_file "$dir/checkpoint.bin" $pid
worker=$(pgrep -P $pid | head -n 1)
[ -n "$worker" ] || { echo "no worker process found"; exit 1; }
kill -$signal "$worker"
set +e
wait $pid
got=$?
set -e
kill -KILL "$worker" 2> /dev/null || true
expect_failed_run $got 3 "$out/err" "$regex" "$dir"
"$qdrun" --resume "$dir" -q --workers 1
grep -qx complete "$dir/status"
"$qdrun" "$exp" -o "$out/full" -q --workers 1 "$@"
same_results "$(run_dir "$out/full")" "$dir"
echo "process fault ($mode) ok"
