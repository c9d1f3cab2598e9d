#!/usr/bin/env bash
# A run killed with SIGKILL in the middle of a loop resumes from its last committed checkpoint and
# ends byte for byte like an uninterrupted run (checkpoints are written in the background, so this
# also covers a kill while a checkpoint is being written).
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
shift 3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/full" --quiet --workers 1 "$@"
"$qdrun" "$exp" -o "$out/killed" --quiet --workers 1 "$@" &
pid=$!
dir=""
# Kill as soon as a checkpoint exists and the run has written metrics rows beyond it. The run is
# stopped (SIGSTOP) while each check looks at it and advances only in short slices between checks,
# so a run of a fraction of a second (lp-cma-me) cannot finish between two checks on a busy machine.
for _ in $(seq 1 6000); do
  kill -STOP $pid 2>/dev/null || break
  dir=$(ls -d "$out"/killed/*/seed-* 2>/dev/null | head -n 1 || true)
  if [ -n "$dir" ] && [ -e "$dir/checkpoint.bin" ] && [ "$(wc -l < "$dir/metrics.csv")" -gt 3 ]; then break; fi
  kill -CONT $pid 2>/dev/null || break
  sleep 0.01
done
kill -9 $pid 2>/dev/null || true
wait $pid 2>/dev/null || true
[ -e "$dir/checkpoint.bin" ] || { echo "no checkpoint was written before the kill"; exit 1; }
if grep -qx complete "$dir/status"; then
  echo "the run finished before it could be killed; raise its budget"; exit 1
fi
# What a kill during a checkpoint write can leave behind: appended bytes that no committed
# checkpoint counts, and a compacted archive generation whose checkpoint never committed.
printf 'uncommitted rows' >> "$dir/dataset.bin"
for f in "$dir"/archive-state-*.bin; do printf 'uncommitted records' >> "$f"; done
printf 'half a generation' > "$dir/archive-state-99999.bin"
"$qdrun" --resume "$dir" --quiet --workers 2
[ ! -e "$dir/archive-state-99999.bin" ] || { echo "resume left an uncommitted archive generation behind"; exit 1; }
grep -qx complete "$dir/status"
same_results "$(run_dir "$out/full")" "$dir"
echo "kill and resume ok"
