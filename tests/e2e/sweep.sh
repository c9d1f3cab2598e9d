#!/usr/bin/env bash
# Sweep basics: files x seeds, --evaluations per run, --set-optional only where the key exists,
# larger loops extend finished runs, and a failing run makes the sweep exit non-zero naming it.
source "$(dirname "$0")/lib.sh"
qdrun=$1 smoke=$2 out=$3
rm -rf "$out" "$out-single" "$out-dry"
log=$out.log
"$qdrun" "$smoke/iso.toml" "$smoke/uniform.toml" "$smoke/poms.toml" --seeds 1,2 -o "$out" \
  --evaluations 300 --set-optional representation.max_epochs=7 > "$log"
cat "$log"
grep -q "6 runs: 6 finished, 0 skipped (already complete), 0 failed" "$log"
for d in "$out"/*/seed-*; do grep -qx complete "$d/status"; done
# 300 evaluations: loop 0 takes 100, then 100 per loop (5 x 20) -> 3 loops; uniform: 1 x 2000 per loop.
[ "$(tail -n 1 "$out/smoke-iso/seed-1/metrics.csv" | cut -d, -f3)" -eq 300 ]
grep -q "^max_epochs = 7$" "$out/smoke-poms/seed-2/config.toml"
! grep -q "max_epochs" "$out/smoke-iso/seed-2/config.toml"
# The same runs with seed 1 equal single qdrun runs.
"$qdrun" "$smoke/iso.toml" --seed 1 -o "$out-single" -q --set experiment.loops=3
same_results "$out-single/smoke-iso/seed-1" "$out/smoke-iso/seed-1"
# Extending: loops=4 resumes every run with a larger budget.
"$qdrun" "$smoke/iso.toml" --seeds 1,2 -o "$out" --set experiment.loops=4 | grep -q "2 runs: 2 finished"
grep -q "loops = 4" "$out/smoke-iso/seed-1/config.toml"
# --dry-run estimates what is left to do: 6 loops of iso (600 evaluations) where 4 are done leave
# 200 per run, priced at what the runs' own loop 3 cost; a fresh directory needs all 600, priced
# from the pilot of loop 0 and its offspring. The total line sums the runs.
"$qdrun" "$smoke/iso.toml" --seeds 1,2 -o "$out" --evaluations 600 --dry-run > "$log"
cat "$log"
grep -Eq "^  smoke-iso/seed-1 +[0-9.]+ core-h: 200 evaluations .*\(measured in its loop 3: [0-9.]+ ms/evaluation x [0-9]+ workers?\)$" "$log"
grep -Eq "^  smoke-iso/seed-2 +[0-9.]+ core-h: 200 evaluations .*\(measured in its loop 3: " "$log"
grep -Eq "^sweep: estimated [0-9.]+ core-hours \(episodes [0-9.]+, training [0-9.]+\); on this machine" "$log"
"$qdrun" "$smoke/iso.toml" --seeds 1 -o "$out-dry" --evaluations 600 --dry-run > "$log"
grep -Eq "^  smoke-iso/seed-1 +[0-9.]+ core-h: 600 evaluations .*\(loop 0: [0-9.]+ ms/episode, .*; offspring: [0-9.]+ ms/episode, [0-9]+ steps\)$" "$log"
[ ! -e "$out-dry" ] || { echo "--dry-run created $out-dry"; exit 1; }
# A [cost] table (loop 0's time per evaluation times 1 + 2 n / 1000 after n evaluations) prices a
# breeding run's episodes from the middle of loop 1 (150 evaluations) to that of loop 5 (550); a
# resumed run grows from its measured loop 3 (350). It is not part of a run's configuration: the runs made
# without it are still resumed.
cost=(--set cost.evaluations=[0,1000] --set cost.offspring_time=[1.0,3.0])
"$qdrun" "$smoke/iso.toml" --seeds 1 -o "$out-dry" --evaluations 600 "${cost[@]}" --dry-run > "$log"
grep -Eq "^  smoke-iso/seed-1 .*; offspring: [0-9.]+ ms/episode, [0-9]+ steps; \[cost\]: loop 0's x1.30 to x2.10 over loops 1-5\)$" "$log"
"$qdrun" "$smoke/iso.toml" --seeds 1 -o "$out" --evaluations 600 "${cost[@]}" --dry-run > "$log"
grep -Eq "^  smoke-iso/seed-1 .*\(measured in its loop 3: [0-9.]+ ms/evaluation x [0-9]+ workers?; \[cost\]: that x1.12 to x1.24 over loops 4-5\)$" "$log"
# A run that fails (an unreadable checkpoint) is named, the others still run.
printf 'garbage' > "$out/smoke-poms/seed-1/checkpoint.bin"
rm "$out/smoke-poms/seed-1/archive.csv"; echo running > "$out/smoke-poms/seed-1/status"
set +e
"$qdrun" "$smoke/poms.toml" --seeds 1,2 -o "$out" --evaluations 300 --set-optional representation.max_epochs=7 > "$log"
rc=$?
set -e
cat "$log"
[ $rc -eq 1 ] || { echo "sweep exit code $rc, expected 1"; exit 1; }
grep -q "FAILED smoke-poms/seed-1" "$log"
grep -q "failed runs: smoke-poms/seed-1" "$log"
# experiments/striker/*.toml: base.toml is included by the others and skipped; --dry-run starts nothing.
"$qdrun" "$smoke/../striker/"*.toml --seeds 1,2 -o "$out-dry" --dry-run > "$log"
grep -q "base.toml is included by the other files" "$log"
grep -q "^sweep: 16 runs (16 to do, 0 complete)" "$log"
[ "$(grep -c " plan   striker-" "$log")" -eq 16 ]
[ ! -e "$out-dry" ] || { echo "--dry-run created $out-dry"; exit 1; }
echo "sweep ok"
