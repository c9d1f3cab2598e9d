#!/usr/bin/env bash
# A CVT archive's run directory (issue 34): grid.toml says kind = "cvt" and names centroids.csv, whose
# rows are the centroids (one per cell) and which every cell of archive.csv is nearest to; the same
# seed gives the same centroids; a resumed run reloads them (an edited centroids.csv is refused,
# naming the file) and ends like an uninterrupted run.
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
/usr/bin/python3 - "$full" <<'PY'
import csv, sys
d = sys.argv[1]
cents = [[float(v) for v in r[1:]] for r in list(csv.reader(open(f"{d}/centroids.csv")))[1:]]
rows = list(csv.DictReader(open(f"{d}/archive.csv")))
assert rows, "empty archive"
for r in rows:
    m = [float(r[k]) for k in sorted(k for k in r if k.startswith("measures_"))]
    dist = [sum((a - b) ** 2 for a, b in zip(c, m)) for c in cents]
    best = min(range(len(cents)), key=lambda i: (dist[i], i))
    assert best == int(r["index"]), f"elite in cell {r['index']} is nearest to centroid {best}"
print(f"{len(rows)} elites in their nearest centroid's cell")
PY
# An edited centroids.csv is refused on resume; restored, the resume gives the uninterrupted run.
cp "$split/centroids.csv" "$out/centroids.csv"
sed -i '2s/^0,\(.\)/0,9\1/' "$split/centroids.csv"
"$(dirname "$0")/expect_error.sh" 2 "centroids.csv does not match the checksum grid.toml records" /nonexistent -- \
  "$qdrun" --resume "$split" -q
cp "$out/centroids.csv" "$split/centroids.csv"
"$qdrun" --resume "$split" -q --workers 2
same_results "$full" "$split"
echo "cvt ok"
