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
/usr/bin/python3 "$src/share/qdplot" "$run" --kinds coverage,maps --formats png --dump-data -o "$run/figures" > /dev/null
/usr/bin/python3 - "$run/figures" <<'PY'
import struct, sys
from pathlib import Path
import matplotlib.image
fig = Path(sys.argv[1])
for name, size in (("coverage-striker.png", (800, 600)), ("map-striker-poms.png", (1200, 650))):
    data = (fig / name).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{name}: no PNG signature"
    assert struct.unpack(">II", data[16:24]) == size, f"{name}: size {struct.unpack('>II', data[16:24])}, not {size}"
    pixels = (matplotlib.image.imread(fig / name)[:, :, :3] * 255).astype(int).reshape(-1, 3)
    colours = {tuple(p) for p in pixels}
    drawn = sum(1 for p in pixels if tuple(p) != (255, 255, 255)) / len(pixels)
    assert len(colours) > 20 and drawn > 0.02, f"{name}: {len(colours)} colours, {drawn:.1%} drawn: not a figure"
print("quickstart figures ok")
PY
/usr/bin/python3 "$(dirname "$0")/map_check.py" "$run/figures/map-striker-poms.png"
