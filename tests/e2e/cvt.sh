#!/usr/bin/env bash
# A CVT archive's run directory (issue 34): grid.toml says kind = "cvt" and names centroids.csv, whose
# rows are the centroids (one per cell) and which every cell of archive.csv is nearest to; the same
# seed gives the same centroids; a resumed run reloads them (an edited centroids.csv is refused,
# naming the file) and ends like an uninterrupted run; qdplot reads it with the tools' reader.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/full" -q --workers 2
"$qdrun" "$exp" -o "$out/split" -q --workers 1 --stop-after-loop 1
full=$(run_dir "$out/full") split=$(run_dir "$out/split")
grep -qx 'kind = "cvt"' "$full/grid.toml"
grep -qx 'centroids = "centroids.csv"' "$full/grid.toml"
cmp "$full/centroids.csv" "$split/centroids.csv"
cells=$(sed -n 's/^cells = //p' "$full/grid.toml")
[ "$(($(wc -l < "$full/centroids.csv") - 1))" -eq "$cells" ] || { echo "centroids.csv has not $cells rows"; exit 1; }
# Every elite's cell is the centroid nearest to its descriptor values (brute force, ties to the lower index).
# Read by the tools' reader (share/qdtools), which also checks centroids.csv against grid.toml.
/usr/bin/python3 - "$(dirname "$0")" "$full" <<'PY'
import sys
sys.path.insert(0, sys.argv[1])
from figure_check import runs
grid, archive = runs.read_grid(sys.argv[2]), runs.read_archive(sys.argv[2])
assert grid.is_cvt and archive.cells.size, "not a CVT, or an empty archive"
for cell, m in zip(archive.cells, archive.measures):
    dist = [sum((a - b) ** 2 for a, b in zip(c, m)) for c in grid.centroids.tolist()]
    best = min(range(len(dist)), key=lambda i: (dist[i], i))
    assert best == cell, f"elite in cell {cell} is nearest to centroid {best}"
print(f"{archive.cells.size} elites in their nearest centroid's cell")
PY
# qdplot reads the run (centroids.csv checked against grid.toml) and names its curve "PoMS CVT", so it
# never shares a curve with PoMS on a grid.
/usr/bin/python3 "$(dirname "$0")/../../share/qdplot" "$full" -o "$out/figures" --formats png --kinds coverage,maps \
  --dump-data > "$out/qdplot.log" 2>&1 || { cat "$out/qdplot.log"; exit 1; }
grep -q '"PoMS CVT (1 seed): [0-9]* cells' "$out"/figures/coverage-*.json \
  || { echo "no PoMS CVT curve:"; cat "$out/qdplot.log" "$out"/figures/coverage-*.json; exit 1; }
# An edited centroids.csv is refused on resume; restored, the resume gives the uninterrupted run.
cp "$split/centroids.csv" "$out/centroids.csv"
sed -i '2s/^0,\(.\)/0,9\1/' "$split/centroids.csv"
"$(dirname "$0")/expect_error.sh" 2 "centroids.csv does not match the checksum grid.toml records" /nonexistent -- \
  "$qdrun" --resume "$split" -q
cp "$out/centroids.csv" "$split/centroids.csv"
"$qdrun" --resume "$split" -q --workers 2
same_results "$full" "$split"
echo "cvt ok"
