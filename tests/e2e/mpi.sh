#!/usr/bin/env bash
# mpirun -np 2 and -np 3 on loopback give the serial run's archive and metrics (except wall time).
source "$(dirname "$0")/lib.sh"
mpi_sanitizer_env
qdrun=$1 exp=$2 out=$3; shift 3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/serial" -q --workers 1 "$@"
for n in 2 3; do
  mpi $n "$qdrun" "$exp" -o "$out/np$n" -q "$@"
  dir=$(run_dir "$out/np$n")
  grep -q '^backend = "mpi"' "$dir/provenance.toml"
  grep -q "^workers = $n" "$dir/provenance.toml"
  same_results "$(run_dir "$out/serial")" "$dir"
done
echo "mpi ok"
