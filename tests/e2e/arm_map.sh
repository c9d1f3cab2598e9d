#!/usr/bin/env bash
# qdplot draws the arm's archive (a 2-D grid) from the run directory's grid.toml alone: every cell
# of the map is checked against archive.csv (map_check.py).
source "$(dirname "$0")/lib.sh"
qdrun=$1 src=$2 out=$3
rm -rf "$out"
"$qdrun" "$src/experiments/arm-quickstart.toml" --output "$out" -q
run=$out/arm-quickstart/seed-1
/usr/bin/python3 "$src/share/qdplot" "$run" --kinds maps --formats png --dump-data -o "$out/figures" > /dev/null
/usr/bin/python3 "$(dirname "$0")/map_check.py" "$out/figures/map-arm-mape-iso.png"
