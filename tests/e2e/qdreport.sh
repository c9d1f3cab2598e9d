#!/usr/bin/env bash
# qdreport end to end on a tiny budget: the sweep runs, the figures exist, and the coverage table
# holds the runs' final elites (median over 3 seeds = the middle archive size).
source "$(dirname "$0")/lib.sh"
qdrun=$1 src=$2 out=$3
rm -rf "$out" "$out-dry" "$out.estimate"
# --dry-run: the plan and its estimate, nothing written.
/usr/bin/python3 "$src/share/qdreport" --configs paper-text --environments striker --algorithms iso --seeds 1 --loops 2 \
  -o "$out-dry" --qdrun "$qdrun" --dry-run > "$out.log" 2>&1 || { cat "$out.log"; exit 1; }
grep -Eq "^  striker-iso/seed-1 +[0-9.]+ core-h: 22000 evaluations" "$out.log" || { cat "$out.log"; exit 1; }
grep -q "^sweep: estimated" "$out.log"
[ ! -e "$out-dry" ] || { echo "qdreport --dry-run created $out-dry"; exit 1; }
/usr/bin/python3 "$src/share/qdreport" --configs paper-text --environments striker --algorithms poms,iso,ps-uniform --seeds 1,2,3 \
  --loops 2 --set experiment.iterations=2 --max-epochs 5 --note "a test note" -o "$out" --qdrun "$qdrun" \
  > "$out.log" 2>&1 \
  || { cat "$out.log"; exit 1; }
report=$out/REPORT.md
grep -q "capped at 5 per loop" "$report"
grep -q "^- note: a test note$" "$report"
grep -q "^- runs made on: .*, .* (9 runs)$" "$report"  # CPU and instruction set, from the runs' provenance
for alg in poms iso ps-uniform; do
  sizes=$(for s in 1 2 3; do echo $(($(wc -l < "$out/runs/striker-$alg/seed-$s/archive.csv") - 1)); done | sort -n)
  median=$(sed -n 2p <<< "$sizes")
  name=$(case $alg in poms) echo PoMS;; iso) echo MAPE-Iso;; *) echo $alg;; esac)
  grep -q "^| $name | 3/3 | [0-9]* | $median (" "$report" || { echo "$name: median $median not in the table"; grep "^| $name |" "$report"; exit 1; }
done
grep -q "figures/coverage-striker.png" "$report"
# Commands are written relative to the repository and the report's directory: no paths of this machine.
grep -q '^- report command: `share/qdreport --configs paper-text --environments striker .* -o REPORT_DIR --qdrun ' "$report"
! grep -qF "$(cd "$src" && pwd)" "$report" || { echo "the report holds absolute paths:"; grep -F "$(cd "$src" && pwd)" "$report"; exit 1; }
[ -s "$out/figures/coverage-striker.png" ] && [ -s "$out/figures/map-striker-poms.png" ]
grep -q "^\*\*Autoencoder epochs capped at 5 per loop\*\*" "$report"  # the caption of the tables it affects
grep -q "^| PoMS | 3/3 | .* | \*\*capped at 5\*\* |$" "$report"
grep -q "^| MAPE-Iso | 3/3 | .* | - | - |$" "$report"  # no mixing ratio, no autoencoder
# The mixing ratio column: the median over seeds of each run's mean over its last loop.
mixing=$(/usr/bin/python3 - "$(dirname "$0")" "$out/runs/striker-poms" <<'PY'
import sys
sys.path.insert(0, sys.argv[1])
from figure_check import runs
means = []
for s in (1, 2, 3):
    rows = runs.read_csv(f"{sys.argv[2]}/seed-{s}/metrics.csv")
    last = [r["mixing_ratio"] for r in rows if r["loop"] == rows[-1]["loop"]]
    means.append(sum(last) / len(last))
print(f"{sorted(means)[1]:.2f}")
PY
)
grep -q "^| PoMS | 3/3 | .* | $mixing | \*\*capped at 5\*\* |$" "$report" \
  || { echo "PoMS: mixing ratio $mixing not in the table"; grep "^| PoMS |" "$report"; exit 1; }
# The cost: the dry-run's estimate saved before the first run, the invocation logged, both in the report.
grep -q "^sweep: estimated [0-9.]* core-hours" "$out/estimate.txt"
grep -Eq "^  striker-poms/seed-2 +[0-9.]+ core-h: " "$out/estimate.txt"
! grep -qF "$out" "$out/estimate.txt" || { echo "estimate.txt holds this machine's paths"; cat "$out/estimate.txt"; exit 1; }
[ "$(wc -l < "$out/invocations.csv")" -eq 2 ] && tail -n 1 "$out/invocations.csv" | grep -Eq "^[0-9T:-]+Z,[0-9.]+,0,9 runs: 9 finished" \
  || { cat "$out/invocations.csv"; exit 1; }
grep -q "^## Cost: the estimate against the measured time" "$report"
for name in PoMS MAPE-Iso ps-uniform; do
  grep -Eq "^\| striker \| $name \| 3 \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| ([0-9.]+|n/a) \|$" "$report" \
    || { echo "no cost row for $name"; sed -n '/## Cost/,$p' "$report"; exit 1; }
done
grep -q "^All 9 compared runs: estimate" "$report"
grep -q "^The sweep ran in 1 invocation of qdreport, [0-9.]* h of wall time in all (ratio to the estimate" "$report"
# Episode lengthening: the breeding runs' (PoMS and MAPE-Iso, not ps-uniform) loop-1 time per
# evaluation over their loop 0's, averaged, and the [cost] lines that state it, which qdrun accepts.
expected=$(/usr/bin/python3 - "$(dirname "$0")" "$out/runs" <<'PY'
import sys
sys.path.insert(0, sys.argv[1])
from figure_check import runs
ratios, middle = [], None
for alg in ("poms", "iso"):
    for s in (1, 2, 3):
        rows = runs.read_csv(f"{sys.argv[2]}/striker-{alg}/seed-{s}/metrics.csv")
        end = {int(r["loop"]): r for r in rows}
        work = lambda r: r["wall_seconds"] - r["train_seconds"]
        e0, e1 = int(end[0]["evaluations"]), int(end[1]["evaluations"])
        ratios.append((work(end[1]) - work(end[0])) / (e1 - e0) / (work(end[0]) / e0))
        middle = (e0 + e1) // 2
print(f"{middle} {sum(ratios) / len(ratios):.2f}")
PY
)
read -r middle factor <<< "$expected"
grep -q "^## Episode lengthening: time per evaluation against loop 0's" "$report"
grep -q "^striker, 6 runs:$" "$report"
grep -q "^| time per evaluation / loop 0's | $factor |$" "$report" \
  || { echo "expected $factor"; sed -n '/## Episode lengthening/,$p' "$report"; exit 1; }
grep -q "^evaluations = \[0, $middle\]$" "$report" && grep -q "^offspring_time = \[1.0, $factor\]$" "$report"
"$qdrun" "$src/experiments/striker/iso.toml" --seeds 1 -o "$out-dry" --set experiment.loops=3 --dry-run \
  --set "cost.evaluations=[0, $middle]" --set "cost.offspring_time=[1.0, $factor]" > "$out.log" \
  || { cat "$out.log"; exit 1; }
grep -q "\[cost\]: loop 0's x" "$out.log"
# Run again: every run is complete; the estimate stays the first one, the invocation is added.
cp "$out/estimate.txt" "$out.estimate"
/usr/bin/python3 "$src/share/qdreport" --configs paper-text --environments striker --algorithms poms,iso,ps-uniform --seeds 1,2,3 \
  --loops 2 --set experiment.iterations=2 --max-epochs 5 -o "$out" --qdrun "$qdrun" > "$out.log" 2>&1 \
  || { cat "$out.log"; exit 1; }
cmp "$out.estimate" "$out/estimate.txt"
[ "$(wc -l < "$out/invocations.csv")" -eq 3 ] && tail -n 1 "$out/invocations.csv" | grep -q ",0,9 runs: 0 finished; 9 skipped" \
  || { cat "$out/invocations.csv"; exit 1; }
grep -q "^The sweep ran in 2 invocations of qdreport" "$report"
# Unfinished runs (a sweep still going): their row says so and how far they got; no NaN anywhere.
for s in 1 2 3; do echo running > "$out/runs/striker-ps-uniform/seed-$s/status"; done
/usr/bin/python3 "$src/share/qdreport" --configs paper-text --no-run --environments striker --algorithms poms,iso,ps-uniform \
  --seeds 1,2,3 --loops 2 -o "$out" --qdrun "$qdrun" > "$out.log" 2>&1 || { cat "$out.log"; exit 1; }
grep -q "^| ps-uniform | 0/3 | [0-9]* so far | none complete | | | | | | - |$" "$report" \
  || { grep "^| ps-uniform |" "$report"; exit 1; }
! grep -qi "nan" "$report" || { grep -i "nan" "$report"; exit 1; }
for s in 1 2 3; do echo complete > "$out/runs/striker-ps-uniform/seed-$s/status"; done

# The report as a study of results/ (share/qdresults): each run without its parameters, checkpoints
# and per-epoch losses, and REPORT.md made again from those files alone, without qdrun (no --qdrun,
# nothing on PATH), with the same tables, a hand-written addendum in its place, and the figures the
# files cannot give again (trajectories, latent codes, losses) as they were drawn.
/usr/bin/python3 "$src/share/qdreport" --configs paper-text --no-run --environments striker --algorithms poms,iso,ps-uniform \
  --seeds 1,2,3 --loops 2 --max-epochs 5 -o "$out" --qdrun "$qdrun" > "$out.log" 2>&1 || { cat "$out.log"; exit 1; }
printf '\n[[addendum]]\nafter = "## striker"\ntext = "Written by hand."\n' >> "$out/study.toml"
s=$out-study
rm -rf "$s"
PATH=/usr/bin:/bin /usr/bin/python3 "$src/share/qdresults" "$out" "$s" > "$s.log" 2>&1 || { cat "$s.log"; exit 1; }
[ ! -e "$s/runs/striker-poms/seed-1/losses.csv" ] && [ ! -e "$s/runs/striker-poms/seed-1/checkpoint.bin" ] \
  && [ ! -e "$s/runs/striker-poms/seed-1/metrics.csv" ] && [ -s "$s/runs/striker-poms/seed-1/metrics.csv.gz" ] \
  || { ls "$s/runs/striker-poms/seed-1"; exit 1; }
zcat "$s/runs/striker-poms/seed-1/archive.csv.gz" | sed -n 1p | grep -q "^index,objective,measures_0,measures_1,measures_2,recn_error$"
[ "$(zcat "$s/runs/striker-poms/seed-1/archive.csv.gz" | wc -l)" -eq "$(wc -l < "$out/runs/striker-poms/seed-1/archive.csv")" ]
diff <(grep "^| " "$report") <(grep "^| " "$s/REPORT.md") || { echo "the study's tables differ from the report's"; exit 1; }
grep -q "^- regenerated from this directory's files (study.toml, runs/): \`share/qdreport --regenerate REPORT_DIR\`$" "$s/REPORT.md"
grep -B2 "^Written by hand.$" "$s/REPORT.md" | grep -q "^</details>$" || { echo "the addendum is not under striker"; exit 1; }
for f in coverage-striker.png map-striker-poms.png traces-striker-poms.png losses-striker-poms.png latents-striker-poms.png; do
  [ -s "$s/figures/$f" ] && grep -q "(figures/$f)" "$s/REPORT.md" || { echo "$f missing from the study"; exit 1; }
done
! find "$s" -name "*.svg" | grep -q . || { echo "a study keeps PNGs only"; exit 1; }
/usr/bin/python3 - "$src/share" "$s" <<'PY'
import sys
sys.path.insert(0, sys.argv[1])
from pathlib import Path
from qdtools import results
root = Path(sys.argv[2])
failures, _, _ = results.check(root, [p for p in root.rglob("*") if p.is_file()])
assert not failures, failures
PY

# An invocation that is stopped (SIGTERM, as when a session ends) logs its time and stops its runs;
# the same command then resumes them.
t=$out-term
rm -rf "$t"
term_cmd=(/usr/bin/python3 "$src/share/qdreport" --configs paper-text --environments striker --algorithms iso --seeds 1 --loops 40
          --set experiment.iterations=2 -o "$t" --qdrun "$qdrun")
"${term_cmd[@]}" > "$t.log" 2>&1 &
pid=$!
for _ in $(seq 600); do
  [ "$(wc -l 2>/dev/null < "$t/runs/striker-iso/seed-1/metrics.csv" || echo 0)" -ge 4 ] && break
  sleep 0.1
done
grep -q ",,running," "$t/invocations.csv" || { cat "$t/invocations.csv"; exit 1; }
kill -TERM "$pid"
rc=0; wait "$pid" || rc=$?
[ "$rc" -eq 143 ] || { echo "qdreport exited with $rc after SIGTERM"; cat "$t.log"; exit 1; }
grep -Eq "^[0-9T:-]+Z,[0-9.]+,interrupted," "$t/invocations.csv" || { cat "$t/invocations.csv"; exit 1; }
! pgrep -f -- "--output $t/runs" > /dev/null || { echo "runs of the stopped sweep still running"; exit 1; }
grep -vq "^complete" "$t/runs/striker-iso/seed-1/status"
"${term_cmd[@]}" > "$t.log" 2>&1 || { cat "$t.log"; exit 1; }
grep -q "^complete" "$t/runs/striker-iso/seed-1/status"
grep -q "^The sweep ran in 2 invocations of qdreport, [0-9.]* h of wall time in all" "$t/REPORT.md"

# The diagnostics: PoMS's loop-1 epochs as its training.csv has them, its elites' median parameter norm.
read -r ep1 norm < <(/usr/bin/python3 - "$(dirname "$0")" "$out/runs/striker-poms/seed-1" <<'PY'
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from figure_check import runs
d = sys.argv[2]
ep = [r["epochs"] for r in runs.read_csv(f"{d}/training.csv", text=True)]
norms = [np.linalg.norm([v for k, v in r.items() if k.startswith("solution_")]) for r in runs.read_csv(f"{d}/archive.csv")]
print(ep[1], f"{np.median(norms):.2f}")
PY
)
grep -q "^## Diagnostics: mixing ratio, training, parameter norms$" "$report"
grep -q "^| PoMS | 1 | [0-9]* | [0-9]* | $ep1 | .* | $norm | [0-9.]* |$" "$report" \
  || { echo "PoMS seed 1: loop-1 epochs $ep1, median norm $norm not in the diagnostics"; grep "^| PoMS | 1 |" "$report"; exit 1; }
grep -q "^| PoMS | 3 | [0-9.]* ([0-9]*) |$" "$report"  # its mixing ratio, the paper's aggregation over 3 seeds
grep -q "^- configuration set: the paper's text" "$report"

# The reference set by default (runs named reference-<env>-<alg>); no epoch cap by default, and the
# Walker's coverage both ways: % of its 12 500 cells and of 50 000.
w=$out-walker
rm -rf "$w"
/usr/bin/python3 "$src/share/qdreport" --environments bipedal-walker --algorithms iso --seeds 1 --loops 2 \
  --set experiment.iterations=1 --set experiment.batch=20 --set experiment.initial_samples=40 -o "$w" \
  --qdrun "$qdrun" > "$w.log" 2>&1 || { cat "$w.log"; exit 1; }
grep -q "^- autoencoder epochs: .*no cap" "$w/REPORT.md"
! grep -qi "capped" "$w/REPORT.md"
grep -q "^- configuration set: the reference code's configurations" "$w/REPORT.md"
elites=$(($(wc -l < "$w/runs/reference-bipedal-walker-iso/seed-1/archive.csv") - 1))
read -r p1 p2 < <(/usr/bin/python3 -c "print(f'{100 * $elites / 12500:.2f} {100 * $elites / 50000:.2f}')")
grep -q "| coverage % of 12500 | coverage % of 50000 |" "$w/REPORT.md"
grep -q "^| MAPE-Iso | 1/1 | [0-9]* | $elites ($elites-$elites) | $p1 ($p1-$p1) | $p2 ($p2-$p2) |" "$w/REPORT.md" \
  || { echo "walker: $elites elites, $p1 % and $p2 % not in the table"; grep "^| MAPE-Iso |" "$w/REPORT.md"; exit 1; }
grep -q "figures/coverage-bipedal-walker.png" "$w/REPORT.md"
echo "qdreport ok"
