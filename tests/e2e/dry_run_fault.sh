#!/usr/bin/env bash
# --dry-run's pilot runs plugin code (loop 0's episodes): an environment that crashes there ends the
# dry run as a run would, with exit code 3 and one line naming the component, its library and the
# run being estimated; nothing is written.
source "$(dirname "$0")/lib.sh"
qdrun=$1 plugins=$2 out=$3
[ -z "${ASAN_OPTIONS:-}" ] || export ASAN_OPTIONS="$ASAN_OPTIONS:handle_segv=0:detect_leaks=0"
rm -rf "$out" "$out-runs"
mkdir -p "$out"
cat > "$out/fault.toml" <<TOML
[experiment]
name = "fault"
seed = 3
loops = 4
iterations = 3
batch = 10
initial_samples = 30

[environment]
type = "fault-arm"
fault = "segfault"
fault_loop = 0
fault_iteration = 0
fault_offspring = 4

[policy]
hidden = [4]

[mutator]
type = "iso"
TOML
set +e
"$qdrun" "$out/fault.toml" --plugin-path "$plugins" --seeds 1 -o "$out-runs" --dry-run > "$out/log" 2> "$out/err"
rc=$?
set -e
cat "$out/err"
[ $rc -eq 3 ] || { echo "exit code $rc, expected 3"; exit 1; }
[ "$(wc -l < "$out/err")" -eq 1 ]
grep -q "^qdrun: error: worker process 1 (pid [0-9]*) was killed by signal 11 (Segmentation fault) in rollout() of environment 'fault-arm' (.*qd_fault.so) (offspring 4 of loop 0, iteration 0) (in the --dry-run estimate of fault/seed-1)$" "$out/err"
[ ! -e "$out-runs" ] || { echo "--dry-run created $out-runs"; exit 1; }
echo "dry-run fault ok"
