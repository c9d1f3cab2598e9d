#!/usr/bin/env bash
# Reliability campaigns (not part of the test suite; minutes): what kills and corruption do to runs.
#   scripts/reliability.sh [QDRUN] [KILLS=20] [FLIPS_PER_FILE=40]
# 1. Random kills: a run is killed with SIGKILL at a random moment, resumed, and compared with an
#    uninterrupted run (archive byte for byte, logs without their time columns).
# 2. Bit flips: one bit of a state file (checkpoint.bin, archive-state-*.bin, dataset.bin) of a
#    stopped run is flipped at positions spread over the file, then the run is resumed: it must be
#    refused (exit 2) or, if it resumes, end identical to the uninterrupted run. A resume that ends
#    differently is a silent change; there must be none.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
qdrun=${1:-$root/build/bin/qdrun}
kills=${2:-20}
flips=${3:-40}
source "$root/tests/e2e/lib.sh"
set +e
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
exp=$root/experiments/smoke/poms.toml
budget=(--set experiment.loops=12 --set experiment.iterations=20)
"$qdrun" "$exp" -o "$work/full" -q --workers 1 "${budget[@]}" || { echo "the reference run failed"; exit 1; }
full=$(run_dir "$work/full")

identical=0 differed=0 no_checkpoint=0
for k in $(seq 1 "$kills"); do
  rm -rf "$work/k"
  "$qdrun" "$exp" -o "$work/k" -q --workers 1 "${budget[@]}" & pid=$!
  sleep "$(python3 -c "import random; print(random.uniform(0.3, 3.0))")"
  kill -9 $pid 2> /dev/null; wait $pid 2> /dev/null
  dir=$(run_dir "$work/k")
  if grep -qx complete "$dir/status" 2> /dev/null; then identical=$((identical + 1)); continue; fi
  if [ ! -e "$dir/checkpoint.bin" ]; then no_checkpoint=$((no_checkpoint + 1)); continue; fi
  "$qdrun" --resume "$dir" -q --workers 2 > /dev/null 2>&1
  if same_results "$full" "$dir" > /dev/null 2>&1; then identical=$((identical + 1)); else differed=$((differed + 1)); fi
done
echo "random kills: $kills trials, $identical identical resumes, $no_checkpoint killed before the first checkpoint, $differed different"

"$qdrun" "$exp" -o "$work/stop" -q --workers 1 "${budget[@]}" --stop-after-loop 5 || exit 1
stop=$(run_dir "$work/stop")
cp -a "$stop" "$work/pristine"
trials=0 refused=0 same=0 silent=0
for f in checkpoint.bin dataset.bin $(cd "$stop" && ls archive-state-*.bin); do
  size=$(stat -c %s "$stop/$f")
  for i in $(seq 0 $((flips - 1))); do
    rm -rf "$stop" && cp -a "$work/pristine" "$stop"
    at=$(( (size - 1) * i / (flips - 1) ))
    python3 -c "import sys; p, i, b = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]); d = bytearray(open(p, 'rb').read()); d[i] ^= 1 << b; open(p, 'wb').write(d)" "$stop/$f" "$at" $((i % 8))
    trials=$((trials + 1))
    "$qdrun" --resume "$stop" -q --workers 1 > /dev/null 2>&1; code=$?
    if [ $code -eq 2 ]; then refused=$((refused + 1))
    elif [ $code -eq 0 ] && same_results "$full" "$stop" > /dev/null 2>&1; then same=$((same + 1))
    else silent=$((silent + 1)); echo "  silent change: $f byte $at bit $((i % 8)) (exit $code)"; fi
  done
done
echo "bit flips: $trials trials, $refused refused corruptions, $same identical resumes, $silent silent changes"
[ "$differed" -eq 0 ] && [ "$silent" -eq 0 ]
