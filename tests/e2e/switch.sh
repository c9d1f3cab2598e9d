#!/usr/bin/env bash
# Changing [mutator] type = "iso" to "uniform" in an experiment file switches the algorithm with
# no rebuild: the run completes and its resolved configuration names the new mutator.
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3
rm -rf "$out"; mkdir -p "$out"
sed 's/^type = "iso"/type = "uniform"/; /^sigma/d' "$exp" > "$out/exp.toml"
grep -q '^type = "uniform"' "$out/exp.toml"
"$qdrun" "$out/exp.toml" -o "$out/runs" -q
dir=$(run_dir "$out/runs")
grep -qx complete "$dir/status"
mutator=$(awk '/^\[mutator\]/{m=1; next} /^\[/{m=0} m && /^type/{print $3}' "$dir/config.toml")
[ "$mutator" = "'uniform'" ] || { echo "resolved mutator is $mutator"; exit 1; }
echo "switch ok"
