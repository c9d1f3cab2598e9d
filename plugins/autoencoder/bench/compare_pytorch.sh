#!/usr/bin/env bash
# Compares the autoencoder plugin with PyTorch (CPU, OpenBLAS) on the same model and workload:
# N = 5000 vectors U(-1,1), P = 2052, HD 100, LD 50, batch 64, float32, Adam lr 1e-5.
#
#   plugins/autoencoder/bench/compare_pytorch.sh
#
# Environment:
#   BUILD_DIR         build tree holding (or to receive) bin/autoencoder_bench
#                     (default: <repo>/build-autoencoder-bench, configured with only this plugin)
#   EPOCHS            timed epochs per configuration (default 3)
#   REALISTIC_EPOCHS  epochs of the realistic loop (3000 x 1635, loop 1); 0 skips it (default 200)
#   OMP_WAIT_POLICY   default passive (both sides)
#   REALISTIC_THREADS threads of the realistic loop (default 0 = all cores, the plugin default)
#
# Not part of the tests: it installs packages (root) and takes a few minutes on 2 cores.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
build="${BUILD_DIR:-$repo/build-autoencoder-bench}"
epochs="${EPOCHS:-3}"
realistic_epochs="${REALISTIC_EPOCHS:-200}"
realistic_threads="${REALISTIC_THREADS:-0}"
# Both sides use libgomp. On a shared machine (2 cores, several users) spinning OpenMP threads
# turn every barrier into a scheduler time slice (measured: ours at 2 threads 1730 ms/epoch active
# vs 130 ms passive, same load); passive waiting is applied to both sides alike.
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}"
py=/usr/bin/python3  # Debian's python with python3-torch, NOT a pyenv python3 on PATH

echo "== packages"
if ! dpkg -s python3-torch libopenblas0-pthread >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y python3-torch libopenblas0-pthread || { apt-get update && apt-get install -y python3-torch libopenblas0-pthread; }
fi

echo "== does PyTorch use OpenBLAS?"
"$py" - <<'EOF'
import torch
cfg = torch.__config__.show()
print("\n".join(l for l in cfg.splitlines() if "BLAS" in l or "CPU capability" in l))
torch.ones(8, 8) @ torch.ones(8, 8)
libs = sorted({l.split()[-1] for l in open("/proc/self/maps") if "blas" in l.lower() and ".so" in l})
print("loaded:", *libs, sep="\n  ")
if not any("openblas" in l for l in libs):
    raise SystemExit("PyTorch does not use OpenBLAS here")
EOF

echo "== building autoencoder_bench in $build"
if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S "$repo" -B "$build" -G Ninja -DQD_ONLY_DIRS=autoencoder -DQD_BUILD_TESTS=OFF >/dev/null
fi
ninja -C "$build" -j2 autoencoder_bench >/dev/null

# Debian's OpenBLAS is DYNAMIC_ARCH; it may not know this CPU (or the environment may pin
# Haswell, AVX2 only). Try the AVX-512 kernels and keep the faster one.
echo "== OPENBLAS_CORETYPE (1 thread, best epoch)"
best_core="" best_ms=""
for core in SkylakeX Cooperlake; do
  ms=$(OPENBLAS_CORETYPE=$core "$py" "$here/torch_bench.py" 1 --epochs 2 --offspring 0 | awk '/^torch_epoch_ms_t1/{print $2}')
  echo "  $core: $ms ms/epoch"
  if [[ -z "$best_ms" ]] || awk -v a="$ms" -v b="$best_ms" 'BEGIN{exit !(a < b)}'; then best_core=$core best_ms=$ms; fi
done
export OPENBLAS_CORETYPE=$best_core
echo "  faster: $OPENBLAS_CORETYPE"

out="$(mktemp)"
trap 'rm -f "$out"' EXIT
echo "== PyTorch"
"$py" "$here/torch_bench.py" 1 --epochs "$epochs" --offspring 1 | tee -a "$out"
"$py" "$here/torch_bench.py" 2 --epochs "$epochs" --offspring 1 | grep -v '^torch_version' | tee -a "$out"
echo "== ours"
"$build/bin/autoencoder_bench" --epochs "$epochs" --realistic-epochs "$realistic_epochs" --realistic-threads "$realistic_threads" | tee -a "$out"

echo "== summary (OMP_WAIT_POLICY=$OMP_WAIT_POLICY, OPENBLAS_CORETYPE=$OPENBLAS_CORETYPE)"
awk -v realistic="$realistic_epochs" '
  { v[$1] = $2 }
  /^torch_offspring_ms/ { if (!("to" in v) || $2 < v["to"]) v["to"] = $2 }
  END {
    ours = (v["ours_epoch_ms_t1"] < v["ours_epoch_ms_t2"]) ? v["ours_epoch_ms_t1"] : v["ours_epoch_ms_t2"]
    torch = (v["torch_epoch_ms_t1"] < v["torch_epoch_ms_t2"]) ? v["torch_epoch_ms_t1"] : v["torch_epoch_ms_t2"]
    printf "epoch ms        ours t1 %s  t2 %s | pytorch t1 %s  t2 %s\n", v["ours_epoch_ms_t1"], v["ours_epoch_ms_t2"], v["torch_epoch_ms_t1"], v["torch_epoch_ms_t2"]
    printf "epoch ratio     ours best / pytorch best = %.3f (target <= 0.5): %s\n", ours / torch, (ours / torch <= 0.5) ? "PASS" : "FAIL"
    printf "offspring ms    ours %s | pytorch %s (%s)\n", v["ours_offspring_ms"], v["to"], "jacobians + J^T xi"
    printf "offspring ratio pytorch / ours = %.1fx (target >= 20x): %s\n", v["to"] / v["ours_offspring_ms"], (v["to"] / v["ours_offspring_ms"] >= 20) ? "PASS" : "FAIL"
    if (realistic > 0) {
      printf "realistic loop  3000 x 1635, loop 1, threads %s (0 = all): %s epochs in %s s (%s ms/epoch, stopped early: %s)\n", v["realistic_threads"], v["realistic_epochs"], v["realistic_total_s"], v["realistic_epoch_ms"], v["realistic_stopped_early"]
      printf "                extrapolated: 2000 epochs = %.0f s; 20000 epochs (loop 0 of the reference) = %.0f s\n", v["realistic_epoch_ms"] * 2, v["realistic_epoch_ms"] * 20
    }
  }' "$out"
