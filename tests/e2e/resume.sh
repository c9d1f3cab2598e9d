#!/usr/bin/env bash
# A run stopped after loop 2 and resumed equals an uninterrupted run, byte for byte in archive and
# metrics (except wall time). The resumed run uses another worker count on purpose.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/full" --quiet --workers 2
"$qdrun" "$exp" -o "$out/split" --quiet --workers 2 --stop-after-loop 2
dir=$(run_dir "$out/split")
grep -q "stopped after loop 2" "$dir/status"
[ ! -e "$dir/archive.csv" ] || { echo "a stopped run must not look complete"; exit 1; }
# Simulate rows written after the checkpoint by a run that was killed mid-loop: resume cuts them.
echo "9,9,9,9,9,9,9,9,9,9,9" >> "$dir/metrics.csv"
"$qdrun" --resume "$dir" --quiet --workers 1
grep -qx complete "$dir/status"
same_results "$(run_dir "$out/full")" "$dir"
echo "resume ok"
