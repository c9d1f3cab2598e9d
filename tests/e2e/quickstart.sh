#!/usr/bin/env bash
# The README's quick start as CI runs it: experiments/quickstart.toml at its own reduced budget, then
# the two figures scripts/quickstart.sh draws into the run directory. Both must be PNGs of the
# documented size that matplotlib drew, and the map must show exactly the run's archive.
source "$(dirname "$0")/lib.sh"
qdrun=$1 src=$2 out=$3
shift 3  # more arguments go to qdrun (the sanitizer build shortens the run)
rm -rf "$out"
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}  # as scripts/quickstart.sh
start=$(date +%s)
"$qdrun" "$src/experiments/quickstart.toml" --output "$out" -q "$@"
echo "qdrun: $(($(date +%s) - start)) s"
run=$out/quickstart/seed-500
grep -qx complete "$run/status"
/usr/bin/python3 "$src/share/qdplot" "$run" --kinds coverage,maps --color occupancy --formats png --dump-data -o "$run/figures" > /dev/null
/usr/bin/python3 - "$(dirname "$0")" "$run/figures" <<'PY'
import sys
sys.path.insert(0, sys.argv[1])
from pathlib import Path
from figure_check import drawn, png_size
fig = Path(sys.argv[2])
for name, size in (("coverage-striker.png", (800, 600)), ("map-striker-poms.png", (1200, 650))):
    assert png_size(fig / name) == size, f"{name}: size {png_size(fig / name)}, not {size}"
    ok, what = drawn(fig / name)
    assert ok, f"{name}: {what}: not a figure"
print("quickstart figures ok")
PY
/usr/bin/python3 "$(dirname "$0")/map_check.py" "$run/figures/map-striker-poms.png"
