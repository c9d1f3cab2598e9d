#!/usr/bin/env bash
# qdreport end to end on a tiny budget: the sweep runs, the figures exist, and the coverage table
# holds the runs' final elites (median over 3 seeds = the middle archive size).
source "$(dirname "$0")/lib.sh"
qdrun=$1 src=$2 out=$3
rm -rf "$out"
/usr/bin/python3 "$src/share/qdreport" --environments striker --algorithms poms,iso,ps-uniform --seeds 1,2,3 \
  --loops 2 --set experiment.iterations=2 --max-epochs 5 --note "a test note" -o "$out" --qdrun "$qdrun" \
  > "$out.log" 2>&1 \
  || { cat "$out.log"; exit 1; }
report=$out/REPORT.md
grep -q "capped at 5 per loop" "$report"
grep -q "^- note: a test note$" "$report"
for alg in poms iso ps-uniform; do
  sizes=$(for s in 1 2 3; do echo $(($(wc -l < "$out/runs/striker-$alg/seed-$s/archive.csv") - 1)); done | sort -n)
  median=$(sed -n 2p <<< "$sizes")
  name=$(case $alg in poms) echo PoMS;; iso) echo MAPE-Iso;; *) echo $alg;; esac)
  grep -q "^| $name | 3/3 | [0-9]* | $median (" "$report" || { echo "$name: median $median not in the table"; grep "^| $name |" "$report"; exit 1; }
done
grep -q "figures/coverage-striker.png" "$report"
[ -s "$out/figures/coverage-striker.png" ] && [ -s "$out/figures/map-striker-poms.png" ]
echo "qdreport ok"
