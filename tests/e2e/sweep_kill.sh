#!/usr/bin/env bash
# A sweep killed with SIGKILL and started again finishes only what is missing:
#  * its child runs die with it (PR_SET_PDEATHSIG), even when only the sweep process is killed;
#  * a run that was complete is not run again (archive.csv keeps its inode and mtime);
#  * the run that was interrupted after a checkpoint is resumed, one that died before its first
#    checkpoint is started again cleanly, and both equal uninterrupted runs byte for byte.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
budget=(--set experiment.loops=300 --set experiment.iterations=10 --set experiment.batch=50)
ename=$(awk -F'"' '/^name/{print $2; exit}' "$exp")
runs=$out/sweep/$ename

# Uninterrupted references.
for s in 2 4; do "$qdrun" "$exp" --seed $s -o "$out/ref" -q --workers 1 "${budget[@]}"; done

# Seed 4 "died before its first checkpoint": a config and a partial log, no checkpoint.bin.
mkdir -p "$runs/seed-4"
cp "$out/ref/$ename/seed-4/config.toml" "$runs/seed-4/"
echo running > "$runs/seed-4/status"
head -n 1 "$out/ref/$ename/seed-4/metrics.csv" > "$runs/seed-4/metrics.csv"
echo "0,0,1,1,1,,1,0,0,0,0" >> "$runs/seed-4/metrics.csv"

# One run at a time, so seed 1 completes while seed 2 is in progress and 3, 4 wait. setsid makes
# the sweep the leader of its own process group.
setsid "$qdrun" "$exp" --seeds 1,2,3,4 -o "$out/sweep" --jobs 1 "${budget[@]}" > "$out/first.log" 2>&1 &
sweep=$!
caught=0
for _ in $(seq 1 6000); do
  if [ -f "$runs/seed-1/archive.csv" ] && [ -f "$runs/seed-2/checkpoint.bin" ] && grep -qx running "$runs/seed-2/status" 2>/dev/null; then
    caught=1; break
  fi
  kill -0 $sweep 2>/dev/null || break
  sleep 0.02
done
children=$(ps -o pid= --ppid $sweep || true)
kill -9 $sweep 2>/dev/null || true
wait $sweep 2>/dev/null || true
[ $caught -eq 1 ] || { echo "never saw seed 1 complete with seed 2 in progress"; cat "$out/first.log"; exit 1; }
[ -n "$children" ] || { echo "the sweep had no child run at the time of the kill"; exit 1; }
for c in $children; do
  for _ in $(seq 1 500); do kill -0 "$c" 2>/dev/null || break; sleep 0.02; done
  if kill -0 "$c" 2>/dev/null; then kill -9 "$c"; echo "child $c outlived the sweep"; exit 1; fi
done
kill -9 -- -$sweep 2>/dev/null || true  # nothing should be left in the group; make sure

grep -qx complete "$runs/seed-1/status"
! grep -qx complete "$runs/seed-2/status" || { echo "seed 2 finished although it was killed"; exit 1; }
[ ! -e "$runs/seed-3" ] || [ ! -e "$runs/seed-3/checkpoint.bin" ]
before=$(stat -c '%i %y %s' "$runs/seed-1/archive.csv" "$runs/seed-1/metrics.csv")

"$qdrun" "$exp" --seeds 1,2,3,4 -o "$out/sweep" --jobs 2 "${budget[@]}" > "$out/second.log" 2>&1 \
  || { cat "$out/second.log"; exit 1; }
cat "$out/second.log"
grep -q "skip   $ename/seed-1 (complete" "$out/second.log"
grep -q "start  $ename/seed-2 (resume" "$out/second.log"
grep -q "start  $ename/seed-3 (fresh)" "$out/second.log"
grep -q "start  $ename/seed-4 (restart" "$out/second.log"
grep -q "4 runs: 3 finished, 1 skipped (already complete), 0 failed" "$out/second.log"
[ "$before" = "$(stat -c '%i %y %s' "$runs/seed-1/archive.csv" "$runs/seed-1/metrics.csv")" ] \
  || { echo "the complete run seed 1 was touched"; exit 1; }
for s in 1 2 3 4; do grep -qx complete "$runs/seed-$s/status"; done
ls "$runs/seed-2"/provenance-resume-loop-*.toml > /dev/null  # it really was resumed
for s in 2 4; do same_results "$out/ref/$ename/seed-$s" "$runs/seed-$s"; done

# A third start has nothing to do; a larger budget extends every run.
"$qdrun" "$exp" --seeds 1,2,3,4 -o "$out/sweep" "${budget[@]}" | grep -q "4 runs: 0 finished, 4 skipped"
echo "sweep kill/resume ok"
