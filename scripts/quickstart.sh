#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install the dependencies (with matplotlib for the
# figures), build qdrun and its plugins, run PoMS on the Striker at a reduced budget
# (experiments/quickstart.toml, about a minute on 2 cores) and draw its coverage curve and archive
# map into the run directory. Extra arguments go to qdrun, e.g.
#   scripts/quickstart.sh --set mutator.type=poms-no-jacobian
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh --plots
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DQD_BUILD_TESTS=OFF -DQD_ONLY_DIRS= -DQD_EXCLUDE_DIRS= > /dev/null
cmake --build build --parallel
rm -rf runs/quickstart
# Training spins less on a busy machine (plugins/autoencoder/README.md, "Shared machines").
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
start=$(date +%s)
./build/bin/qdrun experiments/quickstart.toml --output runs "$@"
echo "qdrun took $(($(date +%s) - start)) s"
run=$(echo runs/quickstart/seed-*)  # seed-500, or the seed given with --seed
/usr/bin/python3 share/qdplot "$run" --kinds coverage,maps --color occupancy --formats png -o "$run/figures" > /dev/null
echo "Run directory: $run (config.toml, metrics.csv, archive.csv, grid.toml, ...)"
for png in "$run"/figures/*.png; do echo "Figure:        $png"; done  # coverage-striker.png, map-striker-poms.png
