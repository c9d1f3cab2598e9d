#!/usr/bin/env bash
# qdplot on a fixture of tiny real runs makes every figure kind, as images of the documented size,
# and plots the numbers of the runs' CSV files (checked independently by qdplot_check.py).
source "$(dirname "$0")/lib.sh"
qdrun=$1 src=$2 out=$3
rm -rf "$out"
# Curves: two arm algorithms over three seeds (PoMS has a mixing ratio), made through a sweep.
"$qdrun" "$src/experiments/smoke/iso.toml" "$src/experiments/smoke/poms.toml" --seeds 1,2,3 -o "$out/runs" > /dev/null
# Maps, trajectories, latents and losses: tiny runs of the paper's environments.
"$qdrun" "$src/experiments/striker/poms.toml" "$src/experiments/bipedal-kicker/ps-uniform.toml" \
  "$src/experiments/bipedal-walker/iso.toml" --seeds 1 -o "$out/runs" --set experiment.loops=3 \
  --set experiment.iterations=2 --set experiment.batch=40 --set experiment.initial_samples=200 \
  --set-optional representation.max_epochs=20 > /dev/null
/usr/bin/python3 "$src/share/qdplot" "$out/runs" -o "$out/figures" --dump-data --qdrun "$qdrun" > "$out/qdplot.log"
/usr/bin/python3 "$(dirname "$0")/qdplot_check.py" "$out/runs" "$out/figures"
# Every map, cell by cell, from its run's archive.csv and grid.toml.
/usr/bin/python3 "$(dirname "$0")/map_check.py" "$out"/figures/map-*.png
