#!/usr/bin/env bash
# The examples' Box2D environment as a plugin author uses it: install qd into a fresh prefix, build
# the installed examples/cart-ball (an environment and a 3-D descriptor qdrun has never seen, with
# named bins) against it, run its own test (qd's conformance checks), run its experiment with the
# installed qdrun, and draw every figure with the installed qdplot, which knows nothing of it but
# the run directory: coverage, the occupancy map, the fitness map (its fitness varies) and the
# ball's trajectories, each with labelled axes and a legend, the maps checked cell by cell.
set -euo pipefail
build=$1 src=$2 work=$3
e2e=$src/tests/e2e
consumer_flags=()
if [ "${4:-}" = sanitize ]; then  # a sanitizer build's libqd_core needs the runtime in every program
  san=-fsanitize=address,undefined
  consumer_flags=(-DCMAKE_CXX_FLAGS=$san -DCMAKE_EXE_LINKER_FLAGS=$san -DCMAKE_MODULE_LINKER_FLAGS=$san)
fi
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log" 2>&1 || { cat "$work/install.log"; exit 1; }
example=$work/prefix/share/qd/examples/cart-ball
cmake -S "$example" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF "${consumer_flags[@]}" > "$work/configure.log" 2>&1 \
  || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/build" > "$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }
(cd "$work/build" && ctest --output-on-failure) > "$work/ctest.log" 2>&1 || { cat "$work/ctest.log"; exit 1; }
grep -q "100% tests passed, 0 tests failed out of 1" "$work/ctest.log" || { cat "$work/ctest.log"; exit 1; }
export QD_PLUGIN_PATH=$work/build
"$work/prefix/bin/qdrun" --describe cart-ball | grep -q "steps (integer, default 180"
"$work/prefix/bin/qdrun" "$example/cart-ball.toml" -o "$work/runs" -q
run=$work/runs/cart-ball-poms/seed-1
grep -qx complete "$run/status"
grep -q '^shape = \[3, 24, 8\]$' "$run/grid.toml"
grep -q '^labels = \[\["left", "still", "right"\], \[\], \[\]\]$' "$run/grid.toml"
/usr/bin/python3 "$work/prefix/share/qd/qdplot" "$run" --formats png --dump-data -o "$work/figures" \
  > "$work/qdplot.log" 2>&1 || { cat "$work/qdplot.log"; exit 1; }
/usr/bin/python3 - "$e2e" "$work/figures" "$run" <<'PY'
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from figure_check import drawn, explained, runs
fig, run = Path(sys.argv[2]), Path(sys.argv[3])
failures = []
elites = len(runs.read_archive(run).cells)
for stem in ("coverage-cart-ball", "map-cart-ball-poms", "map-cart-ball-poms-fitness", "traces-cart-ball-poms"):
    if not (fig / f"{stem}.png").exists():
        failures.append(f"{stem}.png was not drawn")
        continue
    ok, what = drawn(fig / f"{stem}.png")
    if not ok:
        failures.append(f"{stem}.png: {what}")
    failures += explained(json.loads((fig / f"{stem}.json").read_text()), stem)
traces = json.loads((fig / "traces-cart-ball-poms.json").read_text())
if (traces["elites"], traces["replayed_as_stored"], traces["columns"]) != (elites, elites, ["main_0", "main_1", "main_2"]):
    failures.append(f"traces: {traces['elites']} paths, {traces['replayed_as_stored']} replayed into their cell, "
                    f"columns {traces['columns']}; the archive holds {elites} elites")
titles = [a["title"] for a in json.loads((fig / "map-cart-ball-poms.json").read_text())["figure"]["axes"]]
if not [t for t in titles if t.startswith("direction still (")]:
    failures.append(f"map panels are not titled with the bins' names: {titles}")
if failures:
    sys.exit("cart-ball figures FAILED:\n  " + "\n  ".join(failures))
print(f"cart-ball figures ok: {elites} elites")
PY
/usr/bin/python3 "$e2e/map_check.py" "$work/figures/map-cart-ball-poms.png" "$work/figures/map-cart-ball-poms-fitness.png"
echo "cart-ball example ok"
