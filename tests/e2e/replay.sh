#!/usr/bin/env bash
# qdrun --replay re-runs a stored elite: it lands in the cell it was stored in, and the picture is
# an SVG document.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
"$qdrun" "$exp" -o "$out" -q
dir=$(run_dir "$out")
cell=$(sed -n 2p "$dir/archive.csv" | cut -d, -f1)
msg=$("$qdrun" --replay "$dir" --cell "$cell" --svg "$out/elite.svg")
grep -q "lands in cell $cell (as stored)" <<< "$msg" || { echo "$msg"; exit 1; }
head -c 4 "$out/elite.svg" | grep -q "<svg"
tail -n 1 "$out/elite.svg" | grep -q "</svg>"
echo "replay ok: $msg"
