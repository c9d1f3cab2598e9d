#!/usr/bin/env bash
# Installs qd into a fresh prefix, builds an out-of-tree plugin against it with find_package(qd)
# and qd_add_plugin(), and runs it through the installed qdrun.
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work.install.log" 2>&1 || { cat "$work.install.log"; exit 1; }
cmake -S "$src/example" -B "$work/example-build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$work.configure.log" 2>&1 || { cat "$work.configure.log"; exit 1; }
cmake --build "$work/example-build" > "$work.build.log" 2>&1 || { cat "$work.build.log"; exit 1; }
test -f "$work/example-build/qd_half_step.so"
# The installed qdrun finds the installed plugins next to itself and the new one on QD_PLUGIN_PATH.
sed 's/^type = "iso"/type = "half-step"/; /^sigma/d' "$src/../../experiments/smoke/iso.toml" > "$work/exp.toml"
listing=$(QD_PLUGIN_PATH="$work/example-build" "$work/prefix/bin/qdrun" --list)
grep -q "half-step" <<< "$listing"
grep -q "poms" <<< "$listing"  # the installed plugins are found next to the installed qdrun
QD_PLUGIN_PATH="$work/example-build" "$work/prefix/bin/qdrun" "$work/exp.toml" -o "$work/runs" -q
grep -qx complete "$work/runs/smoke-iso/seed-7/status"
grep -q "plugin = \"half_step\"" "$work/runs/smoke-iso/seed-7/provenance.toml"
echo "install ok"
