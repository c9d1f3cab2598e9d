#!/usr/bin/env bash
# The plugin guide's example as a user runs it: install qd into a fresh prefix, build
# docs/examples/cart-ball (a Box2D environment and a 3-D descriptor qdrun has never seen) against it,
# run its experiment with the installed qdrun, and draw its archive with the installed qdplot, which
# knows nothing of the descriptor but the run directory's grid.toml. The map is checked cell by cell.
set -euo pipefail
build=$1 src=$2 work=$3
e2e=$src/tests/e2e
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log" 2>&1 || { cat "$work/install.log"; exit 1; }
cmake -S "$src/docs/examples/cart-ball" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$work/configure.log" 2>&1 || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/build" > "$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }
export QD_PLUGIN_PATH=$work/build
"$work/prefix/bin/qdrun" --describe cart-ball | grep -q "steps (integer, default 180"
"$work/prefix/bin/qdrun" "$src/docs/examples/cart-ball/cart-ball.toml" -o "$work/runs" -q
run=$work/runs/cart-ball-poms/seed-1
grep -qx complete "$run/status"
grep -q '^shape = \[3, 8, 24\]$' "$run/grid.toml"
/usr/bin/python3 "$work/prefix/share/qd/qdplot" "$run" --kinds coverage,maps --formats png --dump-data \
  -o "$work/figures" > "$work/qdplot.log"
/usr/bin/python3 "$e2e/map_check.py" "$work/figures/map-cart-ball-poms.png"
echo "out-of-tree example ok: $(($(wc -l < "$run/archive.csv") - 1)) elites"
