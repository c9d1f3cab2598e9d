#!/usr/bin/env bash
# An experiment file of the paper loads, validates and runs end to end with a tiny budget.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"
# What the tiny budget needs besides: a short training, CMA-ME emitters that divide the batch, a
# small CVT.
"$qdrun" "$exp" -o "$out" -q --workers 2 --set experiment.loops=2 --set experiment.iterations=1 \
  --set experiment.batch=6 --set experiment.initial_samples=8 \
  $(grep -q autoencoder "$exp" && echo --set representation.max_epochs=3) \
  $(grep -q '"cma-me"' "$exp" && echo --set mutator.emitters=3) \
  $(grep -q '"cvt"' "$exp" && echo --set descriptor.cells=20 --set descriptor.samples=200)
dir=$(run_dir "$out")
grep -qx complete "$dir/status"
[ "$(($(wc -l < "$dir/metrics.csv") - 1))" -eq 2 ]
echo "ok: $exp"
