#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install the dependencies, build qdrun and its plugins,
# and run the default experiment (experiments/quickstart.toml). Extra arguments go to qdrun,
# e.g. scripts/quickstart.sh --set mutator.type=uniform
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DQD_BUILD_TESTS=OFF -DQD_ONLY_DIRS= -DQD_EXCLUDE_DIRS= > /dev/null
cmake --build build --parallel
out=runs
rm -rf "$out/quickstart"
./build/bin/qdrun experiments/quickstart.toml --output "$out" "$@"
echo "Results: $out/quickstart/seed-1 (metrics.csv, archive.csv, config.toml)"
