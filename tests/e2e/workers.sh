#!/usr/bin/env bash
# 1 worker and 2 workers give identical archives and metrics (except wall time).
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/w1" --quiet --workers 1
"$qdrun" "$exp" -o "$out/w2" --quiet --workers 2
same_results "$(run_dir "$out/w1")" "$(run_dir "$out/w2")"
echo "workers ok"
