#!/usr/bin/env bash
# Run integrity (issue 19): what a hostile user or a broken machine does to a run directory never
# silently loses or changes results.
#   integrity.sh QDRUN EXPERIMENT OUT CASE
# CASE: concurrent_resume | edited_config | copied_without_state | flipped_bits | truncated_metrics |
#       sigterm | full_disk | log_symlink | thread_limit
source "$(dirname "$0")/lib.sh"
qdrun=$1 exp=$2 out=$3 case=$4
rm -rf "$out"
mkdir -p "$out"

# A run of EXP stopped after loop 1 (resumable); prints its directory.
stopped_run() {
  "$qdrun" "$exp" -o "$out/$1" -q --workers 1 --stop-after-loop 1 "${@:2}" > /dev/null
  run_dir "$out/$1"
}
# COMMAND... exits 2 with one line on stderr matching REGEX.
refused() {
  local regex=$1; shift
  local err got
  err=$("$@" 2>&1 >/dev/null) && got=0 || got=$?
  [ "$got" -eq 2 ] || { echo "exit $got, expected 2: $err"; return 1; }
  grep -Eq -- "$regex" <<< "$err" || { echo "stderr does not match /$regex/: $err"; return 1; }
  [ "$(wc -l <<< "$err")" -eq 1 ] || { echo "expected one line: $err"; return 1; }
}

case $case in
concurrent_resume)
  # The first resume holds the directory for its whole life; a second one is refused at once.
  dir=$(stopped_run a --set experiment.iterations=2000)
  "$qdrun" --resume "$dir" -q --workers 1 > /dev/null 2>&1 &
  first=$!
  for _ in $(seq 1 500); do grep -q "^pid $first " "$dir/lock" 2>/dev/null && break; sleep 0.01; done
  refused "is in use by qdrun pid $first on host" "$qdrun" --resume "$dir" -q --workers 1
  # Two fresh runs into one directory: one of them is refused.
  kill $first; wait $first 2>/dev/null || true
  for twin in 1 2; do
    ( "$qdrun" "$exp" -o "$out/twin" -q --workers 1 --set experiment.iterations=500 2> "$out/twin$twin.err" && rc=0 || rc=$?
      echo $rc > "$out/twin$twin.rc" ) &
  done
  wait
  codes=$(cat "$out/twin1.rc" "$out/twin2.rc" | sort | tr '\n' ' ')
  [ "$codes" = "0 2 " ] || { echo "two fresh runs in one directory: exit codes $codes"; cat "$out"/twin*.err; exit 1; }
  ;;
edited_config)
  # config.toml is a readable copy: the checkpoint's configuration is what a resume must match.
  dir=$(stopped_run a)
  sigma=$(sed -n 's/^sigma = //p' "$dir/config.toml")
  cp "$dir/config.toml" "$out/config.orig"
  sed -i 's/^sigma = .*/sigma = 0.25/' "$dir/config.toml"
  refused "mutator.sigma is 0.25 in config.toml .* made with $sigma" "$qdrun" --resume "$dir" -q
  cp "$out/config.orig" "$dir/config.toml"
  sed -i 's/^seed = .*/seed = 2/' "$dir/config.toml"
  refused "experiment.seed is 2 in config.toml .* made with 7" "$qdrun" --resume "$dir" -q
  cp "$out/config.orig" "$dir/config.toml"
  refused "experiment.batch is 3 .* made with" "$qdrun" --resume "$dir" -q --set experiment.batch=3
  refused "experiment.loops = 1 is below the 2 loops that have run" "$qdrun" --resume "$dir" -q --set experiment.loops=1
  # What may change does: the budget and the evaluation backend.
  "$qdrun" --resume "$dir" -q --workers 2 --backend processes --set experiment.loops=5
  grep -qx complete "$dir/status"
  ;;
copied_without_state)
  # A finished run copied without its *.bin files, with the owner's notes: a sweep must not delete it.
  "$qdrun" "$exp" -o "$out/done" -q --workers 1
  dir=$(run_dir "$out/done")
  rm "$dir"/*.bin
  echo "my notes" > "$dir/notes.txt"
  before=$(ls "$dir" | sort | tr '\n' ' ')
  refused "holds results but no checkpoint" "$qdrun" "$exp" --seeds 7 -o "$out/done"
  [ "$(ls "$dir" | sort | tr '\n' ' ')" = "$before" ] || { echo "the sweep changed $dir"; exit 1; }
  grep -q "my notes" "$dir/notes.txt"
  # --resume never removes files qdrun did not write.
  dir=$(stopped_run b)
  echo "cell,score" > "$dir/my-analysis.csv"
  echo "x" > "$dir/latents.csv"
  "$qdrun" --resume "$dir" -q
  [ -s "$dir/my-analysis.csv" ] && [ -s "$dir/latents.csv" ] || { echo "--resume removed a user's file"; exit 1; }
  ;;
flipped_bits)
  # One flipped bit in any state file is refused, naming the file.
  dir=$(stopped_run a)
  for f in "$dir"/checkpoint.bin "$dir"/archive-state-*.bin "$dir"/dataset.bin; do
    cp "$f" "$out/orig"
    size=$(stat -c %s "$f")
    for at in 0 $((size / 3)) $((size / 2)) $((size - 1)); do
      python3 -c "import sys; p, i = sys.argv[1], int(sys.argv[2]); b = bytearray(open(p, 'rb').read()); b[i] ^= 0x10; open(p, 'wb').write(b)" "$f" "$at"
      refused "$(basename "$f")" "$qdrun" --resume "$dir" -q
      cp "$out/orig" "$f"
    done
  done
  "$qdrun" --resume "$dir" -q  # restored: resumes
  grep -qx complete "$dir/status"
  ;;
truncated_metrics)
  dir=$(stopped_run a)
  cp "$dir/metrics.csv" "$out/metrics.orig"
  head -n 3 "$out/metrics.orig" > "$dir/metrics.csv"
  refused "metrics.csv is shorter .* than the checkpoint records" "$qdrun" --resume "$dir" -q
  rm "$dir/metrics.csv"
  refused "metrics.csv is missing" "$qdrun" --resume "$dir" -q
  ;;
sigterm)
  # SIGTERM: one line saying where the run stopped, a status that says how to go on, exit 143;
  # then --resume finishes it.
  "$qdrun" "$exp" -o "$out/a" -q --workers 2 --set experiment.loops=400 --set experiment.iterations=200 2> "$out/err" &
  pid=$!
  for _ in $(seq 1 1000); do
    dir=$(ls -d "$out"/a/*/seed-* 2>/dev/null | head -n 1 || true)
    [ -n "$dir" ] && [ -e "$dir/checkpoint.bin" ] && break
    sleep 0.01
  done
  children=$(pgrep -P $pid || true)
  kill -TERM $pid
  wait $pid && got=0 || got=$?
  [ "$got" -eq 143 ] || { echo "exit $got after SIGTERM, expected 143"; cat "$out/err"; exit 1; }
  grep -Eq "^stopped by SIGTERM at loop [0-9]+ iteration [0-9]+; resume with qdrun --resume $dir$" "$dir/status" \
    || { echo "status: $(cat "$dir/status")"; exit 1; }
  grep -Eq "^qdrun: stopped by SIGTERM at loop" "$out/err" || { echo "stderr: $(cat "$out/err")"; exit 1; }
  [ "$(grep -c . "$out/err")" -eq 1 ] || { echo "expected one line: $(cat "$out/err")"; exit 1; }
  sleep 0.5
  for c in $children; do  # (a zombie waiting for a reaper has ended)
    state=$(ps -o stat= -p "$c" 2> /dev/null || true)
    [ -z "$state" ] || [[ $state == Z* ]] || { echo "worker process $c outlived qdrun ($state)"; exit 1; }
  done
  "$qdrun" --resume "$dir" -q --set experiment.loops=3
  grep -qx complete "$dir/status"
  ;;
full_disk)
  # A file that cannot be written fails the run (system error, exit 4), never a silent gap. The disk
  # is full for qdrun alone: no file of its may grow past 64 KiB (RLIMIT_FSIZE; with SIGXFSZ ignored
  # the write fails with EFBIG, as it fails with ENOSPC on a full disk).
  err=$( (trap '' XFSZ; ulimit -f 64; exec "$qdrun" "$exp" -o "$out/a" -q --workers 1) 2>&1 >/dev/null) && got=0 || got=$?
  [ "$got" -eq 4 ] || { echo "exit $got, expected 4: $err"; exit 1; }
  grep -Eq "$out/a/smoke-poms/seed-7/[a-z0-9._-]+: File too large" <<< "$err" ||
    { echo "the message does not name the run's file and the error: $err"; exit 1; }
  grep -q "^failed: " "$out/a/smoke-poms/seed-7/status" || { echo "status: $(cat "$out/a/smoke-poms/seed-7/status")"; exit 1; }
  ;;
log_symlink)
  # A representation's training log is a run file like the others: a symlink in its place is refused
  # (exit 2, naming it) and the file it points to is never written.
  mkdir -p "$out/a/smoke-poms/seed-7"
  echo "someone else's file" > "$out/elsewhere.csv"
  ln -s "$out/elsewhere.csv" "$out/a/smoke-poms/seed-7/losses.csv"
  refused "losses.csv is a symbolic link" "$qdrun" "$exp" -o "$out/a" -q --workers 1
  [ "$(cat "$out/elsewhere.csv")" = "someone else's file" ] || { echo "written through the symlink"; exit 1; }
  grep -q "^failed: " "$out/a/smoke-poms/seed-7/status" || { echo "status: $(cat "$out/a/smoke-poms/seed-7/status")"; exit 1; }
  ;;
thread_limit)
  # Threads that cannot be created (a container's process limit) are an error, never a hang. The
  # limit binds only an unprivileged user: run as nobody where we are root.
  [ "$(id -u)" -eq 0 ] && command -v setpriv > /dev/null || { echo "SKIPPED: needs root and setpriv"; exit 77; }
  # A checkout under a private directory (mktemp -d is mode 700) is out of nobody's reach.
  setpriv --reuid=65534 --regid=65534 --clear-groups test -x "$qdrun" ||
    { echo "SKIPPED: user nobody cannot run $qdrun (a parent directory is private)"; exit 77; }
  chmod 777 "$out"
  err=$(timeout 60 setpriv --reuid=65534 --regid=65534 --clear-groups bash -c \
        "ulimit -u 3; '$qdrun' '$exp' -o '$out/a' -q --backend threads --workers 8" 2>&1 >/dev/null) && got=0 || got=$?
  [ "$got" -eq 4 ] || { echo "exit $got, expected 4 (124 = hung): $err"; exit 1; }
  grep -q "cannot create evaluation thread" <<< "$err" || { echo "message: $err"; exit 1; }
  ;;
*) echo "unknown case $case"; exit 2 ;;
esac
echo "integrity $case ok"
