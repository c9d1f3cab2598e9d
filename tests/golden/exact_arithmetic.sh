#!/usr/bin/env bash
# Fails when qdrun's binaries contain an instruction whose result the standard leaves to the CPU:
# the approximate reciprocals and reciprocal square roots (rcpps, rsqrtps, AVX-512's rcp14/rsqrt14,
# ...) and the x87 transcendentals (fsin, fyl2x, ...). With them one binary computes other bits on
# another vendor's CPU: Eigen's float sqrt() is rsqrtps plus a Newton step on AVX2, and it made the
# same x86-64-v3 build train the autoencoder to other weights on an AMD EPYC and an Intel Xeon.
# Every other floating-point instruction is exactly rounded, so without these a build gives the same
# bits on every CPU that runs it.
#
#   tests/golden/exact_arithmetic.sh BUILD_DIR    scans BUILD_DIR/bin/qdrun, lib/libqd_core.so, lib/qd/plugins/*.so
set -euo pipefail
build=$1
if ! command -v objdump > /dev/null; then
  echo "SKIPPED: objdump (binutils) is not installed"
  exit 77
fi
shopt -s nullglob
binaries=("$build"/bin/qdrun "$build"/lib/libqd_core.so "$build"/lib/qd/plugins/*.so)
[ -e "$build/bin/qdrun" ] || { echo "no $build/bin/qdrun: build first" >&2; exit 2; }
pattern='^v?(rcp|rsqrt)(ps|ss|pd|sd|ph|sh|14ps|14ss|14pd|14sd|14ph|14sh|28ps|28ss|28pd|28sd)$|^(fsin|fcos|fsincos|fptan|fpatan|fyl2x|fyl2xp1|f2xm1)$'
found=0
for binary in "${binaries[@]}"; do
  # Function and instruction of every match: objdump -d prints "<function>:" before each function.
  hits=$(objdump -d --no-show-raw-insn -C "$binary" | awk -v pat="$pattern" '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ /, "", fn); next }
    $2 ~ pat { count[$2 "  in " substr(fn, 1, 160)]++ }
    END { for (k in count) print "  " count[k] " x " k }')
  if [ -n "$hits" ]; then
    echo "$binary:"
    echo "$hits"
    found=1
  fi
done
if [ "$found" -ne 0 ]; then
  echo "approximate instructions found (above): their last bits are the CPU's, not the standard's. Compute the"
  echo "value with an exactly rounded operation (a scalar std::sqrt in unaryExpr instead of Eigen's"
  echo "sqrt()/cwiseSqrt(), a division instead of a reciprocal)."
  exit 1
fi
echo "exact_arithmetic: ${#binaries[@]} binaries, no approximate instructions"
