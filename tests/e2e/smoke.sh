#!/usr/bin/env bash
# qdrun completes a smoke experiment: status complete, one metrics row per iteration, the final
# archive parses back with one row per elite, and coverage never decreases.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
"$qdrun" "$exp" -o "$out" --quiet --workers 2
dir=$(run_dir "$out")
grep -qx complete "$dir/status"
loops=$(awk -F' = ' '/^loops/{print $2}' "$dir/config.toml")
iters=$(awk -F' = ' '/^iterations/{print $2}' "$dir/config.toml")
rows=$(($(wc -l < "$dir/metrics.csv") - 1))
[ "$rows" -eq $((1 + (loops - 1) * iters)) ] || { echo "metrics rows $rows, expected $((1 + (loops - 1) * iters))"; exit 1; }
elites=$(tail -n 1 "$dir/metrics.csv" | cut -d, -f4)
archive_rows=$(($(wc -l < "$dir/archive.csv") - 1))
[ "$elites" -eq "$archive_rows" ] || { echo "archive has $archive_rows rows, metrics say $elites elites"; exit 1; }
awk -F, 'NR>2 && $4 < prev {print "coverage decreased at row " NR; exit 1} NR>1 {prev=$4}' "$dir/metrics.csv"
echo "smoke ok: $dir ($elites elites)"
