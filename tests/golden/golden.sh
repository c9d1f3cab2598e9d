#!/usr/bin/env bash
# Golden runs: a tiny run of every algorithm (and of each insertion rule) whose results are pinned
# by committed hashes, so that any change to what qdrun computes fails here until it is made
# deliberately (re-run with --update and commit the new hashes, saying why in the commit).
#
#   tests/golden/golden.sh QDRUN OUT_DIR            compare with the committed hashes
#   tests/golden/golden.sh QDRUN OUT_DIR --update   rewrite them
#
# Hashed: archive.csv byte for byte; metrics.csv and training.csv without their wall-clock
# columns. Floating-point results depend on the instruction set the build uses (Eigen's packet size
# changes summation order, FMA contraction rounding), so hashes are kept per instruction-set level
# and build variant, which ctest passes in QD_GOLDEN_VARIANT (QD_ARCH=level: x86-64-v4.sha256 for
# Release, x86-64-v4-relwithdebinfo-sanitize.sha256 for scripts/test.sh --sanitize, ...); a build
# with no file (QD_ARCH=native, another CPU family, a Debug build) is reported as skipped, never as
# passed. To update a variant's file: QD_GOLDEN_VARIANT=<variant> tests/golden/golden.sh ... --update
source "$(cd "$(dirname "$0")/../e2e" && pwd)/lib.sh"
qdrun=$1 out=$2 mode=${3:-check}
root=$(cd "$(dirname "$0")/../.." && pwd)
smoke=$root/experiments/smoke
box2d=(--set experiment.loops=3 --set experiment.iterations=2 --set experiment.batch=16
       --set experiment.initial_samples=24)
# name | experiment file | overrides
runs=(
  "iso|$smoke/iso.toml|"
  "iso-line-dd|$smoke/iso-line-dd.toml|"
  "uniform|$smoke/uniform.toml|"
  "glorot|$smoke/glorot.toml|"
  "poms|$smoke/poms.toml|"
  "poms-no-jacobian|$smoke/poms-no-jacobian.toml|"
  "poms-pca|$smoke/poms-pca.toml|"
  "dde|$smoke/dde.toml|"
  "iso-fitness|$smoke/iso.toml|--set experiment.insertion=fitness"
  "cma-me|$smoke/cma-me.toml|"
  "lp-cma-me|$smoke/lp-cma-me.toml|"
  "poms-cvt|$smoke/poms-cvt.toml|"
  "striker-poms|$root/experiments/striker/poms.toml|${box2d[*]} --set representation.max_epochs=5"
  "walker-iso-line-dd|$root/experiments/bipedal-walker/iso-line-dd.toml|${box2d[*]}"
  "kicker-dde|$root/experiments/bipedal-kicker/dde.toml|${box2d[*]} --set representation.max_epochs=5"
)
rm -rf "$out"
mkdir -p "$out"
hashes=$out/hashes.txt
for entry in "${runs[@]}"; do
  IFS='|' read -r name file overrides <<< "$entry"
  # shellcheck disable=SC2086  # overrides are words
  "$qdrun" "$file" -o "$out/$name" -q --workers 1 $overrides
  dir=$(run_dir "$out/$name")
  {
    printf '%s archive.csv %s\n' "$name" "$(sha256sum < "$dir/archive.csv" | cut -c1-64)"
    printf '%s metrics.csv %s\n' "$name" "$(drop_columns "$dir/metrics.csv" wall_seconds train_seconds | sha256sum | cut -c1-64)"
    printf '%s training.csv %s\n' "$name" "$(drop_columns "$dir/training.csv" seconds | sha256sum | cut -c1-64)"
  } >> "$hashes"
done
class=$(sed -n 's/^instruction_set = "-march=\([^ "]*\).*/\1/p' "$(run_dir "$out/iso")/provenance.toml")
class=${class:-none}${QD_GOLDEN_VARIANT:-}
expected=$root/tests/golden/$class.sha256
if [ "$mode" = "--update" ]; then
  cp "$hashes" "$expected"
  echo "wrote $expected"
  exit 0
fi
if [ ! -f "$expected" ]; then
  echo "SKIPPED: no golden hashes for build class $class; create them with $0 QDRUN OUT --update"
  exit 77
fi
if ! diff "$expected" "$hashes"; then
  echo "results differ from the golden runs (lines above: < committed, > this build)."
  echo "If the change is deliberate, run: tests/golden/golden.sh QDRUN OUT --update, and commit the hashes."
  exit 1
fi
echo "golden: $(wc -l < "$hashes") hashes match ($class)"
