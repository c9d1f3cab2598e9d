#!/usr/bin/env bash
# Every local backend and worker count gives the serial run's archive and metrics (except wall time):
# threads 2, processes 1 (the default for one worker), 2 and 3 against threads 1 (in-process).
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3; shift 3
rm -rf "$out"
"$qdrun" "$exp" -o "$out/serial" -q --backend threads --workers 1 "$@"
for cfg in "threads 2" "processes 1" "processes 2" "processes 3"; do
  read -r backend n <<< "$cfg"
  "$qdrun" "$exp" -o "$out/$backend-$n" -q --backend "$backend" --workers "$n" "$@"
  grep -q "^backend = \"$backend\"" "$(run_dir "$out/$backend-$n")/provenance.toml"
  same_results "$(run_dir "$out/serial")" "$(run_dir "$out/$backend-$n")"
done
echo "backends ok"
