# Shared helpers of the end-to-end tests (sourced).
set -euo pipefail

# Drops the named columns from a CSV file (by header name).
drop_columns() {
  local file=$1; shift
  awk -F, -v drop="$*" 'BEGIN{OFS=","; n=split(drop, d, " "); for(i=1;i<=n;i++) skip[d[i]]=1}
    NR==1{for(i=1;i<=NF;i++) if($i in skip) gone[i]=1}
    {out=""; first=1; for(i=1;i<=NF;i++) if(!(i in gone)){out=out (first?"":",") $i; first=0}; print out}' "$file"
}

# Two run directories hold the same results: archive byte for byte, metrics and training logs
# except their wall-clock columns.
same_results() {
  local a=$1 b=$2
  cmp "$a/archive.csv" "$b/archive.csv" || { echo "archive.csv differs between $a and $b"; return 1; }
  diff <(drop_columns "$a/metrics.csv" wall_seconds train_seconds) <(drop_columns "$b/metrics.csv" wall_seconds train_seconds) \
    || { echo "metrics.csv differs between $a and $b"; return 1; }
  diff <(drop_columns "$a/training.csv" seconds) <(drop_columns "$b/training.csv" seconds) \
    || { echo "training.csv differs between $a and $b"; return 1; }
  for f in "$a"/*.csv; do
    name=$(basename "$f")
    case $name in archive.csv|metrics.csv|training.csv) continue ;; esac
    cmp "$f" "$b/$name" || { echo "$name differs between $a and $b"; return 1; }
  done
}

# The single seed-* run directory under OUT/NAME.
run_dir() { ls -d "$1"/*/seed-* | head -n 1; }
