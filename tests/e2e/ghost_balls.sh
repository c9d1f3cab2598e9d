#!/usr/bin/env bash
# The kicker's ghost balls (environments/bipedal/README.md): episodes depend on the balls earlier
# episodes left in their world, yet one seed gives one archive with 1 or 2 worker threads, and a run
# stopped after loop 1 and resumed equals the uninterrupted one. Worker processes are refused.
source "$(dirname "$0")/lib.sh"
qdrun=$1 ref=$2 out=$3
rm -rf "$out"
mkdir -p "$out"
cat > "$out/ghosts.toml" <<TOML
include = "$ref"
[experiment]
loops = 3
iterations = 2
batch = 30
initial_samples = 100
[environment]
ghost_balls = 4
TOML
"$qdrun" "$out/ghosts.toml" -o "$out/one" --quiet --workers 1
"$qdrun" "$out/ghosts.toml" -o "$out/two" --quiet --workers 2
same_results "$(run_dir "$out/one")" "$(run_dir "$out/two")"
grep -qx 'backend = "threads"' "$(run_dir "$out/two")/provenance.toml"
"$qdrun" "$out/ghosts.toml" -o "$out/split" --quiet --workers 2 --stop-after-loop 1
"$qdrun" --resume "$(run_dir "$out/split")" --quiet --workers 1
same_results "$(run_dir "$out/one")" "$(run_dir "$out/split")"
# The ghosts matter: the same seed without them gives another archive.
"$qdrun" "$out/ghosts.toml" -o "$out/none" --quiet --workers 2 --set environment.ghost_balls=0
! cmp -s "$(run_dir "$out/one")/archive.csv" "$(run_dir "$out/none")/archive.csv" || { echo "ghost balls changed nothing"; exit 1; }
# --dry-run's pilot runs in fresh worlds and says what it leaves out.
# (Its output is read whole first: grep -q would close the pipe early, and pipefail would fail on SIGPIPE.)
dry=$("$qdrun" "$out/ghosts.toml" -o "$out/dry" --dry-run)
grep -q "not priced: what its 4 persistent worlds accumulate" <<< "$dry" ||
  { echo "--dry-run does not say it leaves the ghost balls out: $dry"; exit 1; }
dry=$("$qdrun" "$out/ghosts.toml" -o "$out/dry" --dry-run --set environment.ghost_balls=0)
! grep -q "not priced" <<< "$dry" || { echo "--dry-run without ghost balls says something is not priced: $dry"; exit 1; }
set +e
msg=$("$qdrun" "$out/ghosts.toml" -o "$out/procs" --quiet --backend processes 2>&1)
code=$?
set -e
[ "$code" = 2 ] || { echo "backend processes: exit $code, expected 2"; exit 1; }
grep -q "keeps 4 persistent worlds" <<< "$msg" || { echo "unexpected message: $msg"; exit 1; }
echo "ghost balls ok"
