#!/usr/bin/env bash
# Reliability campaigns (not part of the test suite; about 4-5 minutes on 2 busy cores): what hostile
# conditions, kills and corruption do to runs. Every attack runs without a terminal or a prompt.
#   scripts/reliability.sh [QDRUN] [KILLS=20] [FLIPS_PER_FILE=40]
#   QD_RELIABILITY_ONLY=REGEX scripts/reliability.sh ...   only the verdicts whose name matches, with
#                                                          their logs; no campaigns
# QDRUN is a qdrun of a build with tests (default build/bin/qdrun): the hostile plugins of
# tests/plugins (BUILD/tests/plugins) and the unit tests (BUILD/bin/qd_unit_tests) come with it.
# 1. Hostile conditions: the 20 cases of issue 32 (case N) and 41 further ones (extra N), each ending
#    with the behaviour docs/user-guide.md documents. One verdict line each.
# 2. Random kills: a run is killed with SIGKILL at a random moment, resumed, and compared with an
#    uninterrupted run (archive byte for byte, logs without their time columns).
# 3. Bit flips: one bit of a state file (checkpoint.bin, archive-state-*.bin, dataset.bin) of a
#    stopped run is flipped at positions spread over the file, then the run is resumed: it must be
#    refused (exit 2) or, if it resumes, end identical to the uninterrupted run. A resume that ends
#    differently is a silent change; there must be none.
# Exit code 0 when every verdict is PASS and the campaigns found no difference.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
qdrun=$(realpath "${1:-$root/build/bin/qdrun}")
kills=${2:-20}
flips=${3:-40}
source "$root/tests/e2e/lib.sh"
set +e
build=$(dirname "$(dirname "$qdrun")")
plugins=$build/tests/plugins
unit_tests=$build/bin/qd_unit_tests
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
exp=$root/experiments/smoke/iso.toml
Q=$qdrun
start=$SECONDS
passed=0 failed=0

# verdict NAME FUNCTION: runs the case in a subshell (set -e), one line: PASS, or FAIL and why.
only=${QD_RELIABILITY_ONLY:-}
verdict() {
  local name=$1 fn=$2 log=$work/$2.log rc
  if [ -n "$only" ] && ! grep -Eq -- "$only" <<< "$name"; then return; fi
  # Not in a condition: there, bash would ignore the subshell's set -e.
  (set -e; "$fn") > "$log" 2>&1
  rc=$?
  if [ $rc -eq 0 ]; then
    passed=$((passed + 1)); echo "PASS $name"
  else
    failed=$((failed + 1)); echo "FAIL $name: $(tail -n 4 "$log" | tr '\n' ' ' | cut -c1-400)"
  fi
  if [ -n "$only" ]; then sed 's/^/    /' "$log"; fi
}

# COMMAND... exits with CODE and one line on stderr matching REGEX (nothing on stdout counted).
expect() {
  local code=$1 regex=$2; shift 2
  local err got
  err=$(timeout 60 "$@" 2>&1 > /dev/null) && got=0 || got=$?
  [ "$got" -eq "$code" ] || { echo "exit $got, expected $code: $err"; return 1; }
  [ -z "$regex" ] || grep -Eq -- "$regex" <<< "$err" || { echo "stderr does not match /$regex/: $err"; return 1; }
  [ "$code" -eq 0 ] || [ "$(grep -c . <<< "$err")" -eq 1 ] || { echo "expected one line: $err"; return 1; }
}
refused() { expect 2 "$@"; }

# A run of EXP stopped after loop 1 (resumable) under OUT=$work/NAME; prints its directory.
stopped_run() {
  "$Q" "$exp" -o "$work/$1" -q --workers 1 --stop-after-loop 1 "${@:2}" > /dev/null || return 1
  run_dir "$work/$1"
}
# An uninterrupted run of EXP with ARGS under $work/NAME; prints its directory.
full_run() {
  "$Q" "$exp" -o "$work/$1" -q --workers 1 "${@:2}" > /dev/null || return 1
  run_dir "$work/$1"
}
# Waits until FILE holds a line matching REGEX (a run's lock, say) while PID lives.
wait_for_line() {
  local file=$1 regex=$2 pid=$3
  for _ in $(seq 1 3000); do
    grep -Eq -- "$regex" "$file" 2> /dev/null && return 0
    kill -0 "$pid" 2> /dev/null || { echo "the run ended before $file matched /$regex/"; return 1; }
    sleep 0.01
  done
  echo "timed out waiting for $file"; return 1
}
is_complete() { grep -qx complete "$1/status" || { echo "status of $1: $(cat "$1/status" 2>&1)"; return 1; }; }
long=(--set experiment.loops=6 --set experiment.iterations=1500)  # about 1 s a loop
# The uninterrupted runs results are compared with, each made once, when a case first needs it:
# $(reference ref), $(reference ref6), $(reference reflong), $(reference ref0) (a long loop 0).
reference() {
  case $1 in
  ref) set -- ref ;;
  ref6) set -- ref6 --set experiment.loops=6 ;;
  reflong) set -- reflong "${long[@]}" ;;
  ref0) set -- ref0 "${loop0[@]}" ;;
  esac
  [ -e "$work/$1.done" ] || { full_run "$@" > /dev/null && touch "$work/$1.done"; } || return 1
  run_dir "$work/$1"
}
# Under the sanitizers (scripts/test.sh --sanitize) a deliberate crash or exit() must end as it
# would, not in AddressSanitizer's report.
[ -z "${ASAN_OPTIONS:-}" ] || export ASAN_OPTIONS="$ASAN_OPTIONS:handle_segv=0:detect_leaks=0"

echo "qdrun reliability: $qdrun"
[ -x "$Q" ] || { echo "no qdrun at $Q"; exit 1; }

# ---- Issue 32 ------------------------------------------------------------------------------------
case_01() {  # closed standard descriptors: results equal, nothing written into run files
  for backend in processes threads; do
    for how in "2>&-" ">&- 2>&-" "<&- >&- 2>&-"; do
      rm -rf "$work/c01"
      eval "\"\$Q\" \"\$exp\" -o \"\$work/c01\" --workers 2 --backend $backend $how" || { echo "$backend $how failed"; return 1; }
      d=$(run_dir "$work/c01")
      same_results "$(reference ref)" "$d"
      grep -Eqx "pid [0-9]+ on host .*" "$d/lock" || { echo "lock: $(cat "$d/lock")"; return 1; }
    done
  done
}
case_02() {  # the lock file deleted while a run is live: a second resume is still refused
  d=$(stopped_run c02 "${long[@]}")
  "$Q" --resume "$d" -q --workers 1 & first=$!
  wait_for_line "$d/lock" "^pid $first " $first  # (named once it is held)
  rm "$d/lock"
  refused "is in use by qdrun" "$Q" --resume "$d" -q --workers 1
  wait $first || { echo "the first run failed"; return 1; }
  is_complete "$d"; same_results "$(reference reflong)" "$d"
}
case_03() {  # an edited metrics.csv (same length) is refused naming it
  d=$(stopped_run c03)
  cp "$d/metrics.csv" "$work/c03.metrics"
  python3 - "$d/metrics.csv" <<'PY'
import sys
p = sys.argv[1]; lines = open(p).read().split('\n')
f = lines[3].split(','); e = f[3]; f[3] = e[:-1] + ('1' if e[-1] != '1' else '2'); lines[3] = ','.join(f)
open(p, 'w').write('\n'.join(lines))
PY
  cmp -s "$d/metrics.csv" "$work/c03.metrics" && { echo "the edit did not change the file"; return 1; }
  refused "metrics.csv: its first [0-9]+ bytes differ from what the checkpoint recorded" "$Q" --resume "$d" -q
  cp "$work/c03.metrics" "$d/metrics.csv"
  sed -i '1s/elites/elitez/' "$d/metrics.csv"
  refused "metrics.csv: .*it was edited" "$Q" --resume "$d" -q
  cp "$work/c03.metrics" "$d/metrics.csv"
  "$Q" --resume "$d" -q && is_complete "$d" && same_results "$(reference ref)" "$d"
}
case_04() {  # a hard-linked copy (cp -al) extended: the original is never touched
  orig=$(full_run c04)
  (cd "$orig" && find . -type f -exec md5sum {} + | sort) > "$work/c04.before"
  cp -al "$orig" "$work/c04-copy"
  "$Q" --resume "$work/c04-copy" -q --set experiment.loops=6
  (cd "$orig" && find . -type f -exec md5sum {} + | sort) > "$work/c04.after"
  diff "$work/c04.before" "$work/c04.after" || { echo "extending the copy changed the original"; return 1; }
  is_complete "$orig"
  "$Q" --resume "$orig" -q --set experiment.loops=6
  same_results "$(reference ref6)" "$orig"; same_results "$(reference ref6)" "$work/c04-copy"
}
case_05() {  # the plugin directory a run used is gone at --resume: an error naming the library
  mkdir -p "$work/c05-plugins"; cp "$plugins/shadow/qd_shadow.so" "$work/c05-plugins/"
  sed '/^sigma/d' "$exp" > "$work/c05.toml"  # the shadowing iso declares no parameter
  "$Q" "$work/c05.toml" -o "$work/c05" -q --workers 1 --stop-after-loop 1 --plugin-path "$work/c05-plugins"
  d=$(run_dir "$work/c05")
  grep -q "qd_shadow.so" "$d/provenance.toml"
  rm -rf "$work/c05-plugins"
  refused "\[mutator\] 'iso' came from .*qd_shadow.so .*which no longer exists, but would now come from .*qd_basic.so" \
    "$Q" --resume "$d" -q
}
case_06() {  # replay never writes over a run's own files
  d=$(full_run c06)
  cp -a "$d" "$work/c06.orig"
  refused "that is a file of the run" "$Q" --replay "$d" --all --traces "$d/metrics.csv"
  cell=$(sed -n 2p "$d/archive.csv" | cut -d, -f1)
  refused "that is a file of the run" "$Q" --replay "$d" --cell "$cell" --svg "$d/checkpoint.bin"
  refused "that is a file of the run" "$Q" --replay "$d" --cell "$cell" --svg "$d/archive/../status"
  diff -r "$work/c06.orig" "$d"
  "$Q" --replay "$d" --cell "$cell" > /dev/null  # its own output, beside the run's files
  "$Q" --resume "$d" -q --set experiment.loops=6 && same_results "$(reference ref6)" "$d"
}
case_07() {  # option values that used to be ignored
  refused "--seed needs a value" "$Q" "$exp" -o "$work/c07" --seed ""
  refused "--evaluations -5: a budget is at least 1" "$Q" "$exp" "$root/experiments/smoke/uniform.toml" -o "$work/c07" --evaluations -5
  refused "--stop-after-loop -1: loops are numbered from 0" "$Q" "$exp" -o "$work/c07" --stop-after-loop -1
  refused "--plugin-path /does-not-exist: no such directory" "$Q" "$exp" -o "$work/c07" --plugin-path /does-not-exist
  [ ! -e "$work/c07" ] || { echo "a refused command wrote $work/c07"; return 1; }
}
fault_toml() {  # FAULT, on every offspring of loop 2 iteration 1
  cat <<TOML
[experiment]
name = "fault"
seed = 3
loops = 4
iterations = 3
batch = 40
initial_samples = 30
[environment]
type = "fault-arm"
fault = "$1"
fault_loop = 2
fault_iteration = 1
fault_count = 40
[policy]
hidden = [4]
[mutator]
type = "iso"
sigma = 0.1
TOML
}
case_08() {  # two worker threads fault at once: one report, one non-zero exit, every time
  for f in exit0:3 segfault:139 abort:134; do
    fault_toml "${f%:*}" > "$work/c08.toml"
    for i in 1 2 3 4; do
      rm -rf "$work/c08"
      (exec "$Q" "$work/c08.toml" --plugin-path "$plugins/fault" -q --backend threads --workers 2 -o "$work/c08" 2> "$work/c08.err") \
        && got=0 || got=$?
      [ $got -eq "${f#*:}" ] || { echo "${f%:*} trial $i: exit $got: $(cat "$work/c08.err")"; return 1; }
      [ "$(grep -c . "$work/c08.err")" -eq 1 ] || { echo "${f%:*} trial $i: $(cat "$work/c08.err")"; return 1; }
      grep -q "^failed: .* in rollout() of environment 'fault-arm'" "$work"/c08/*/*/status
    done
  done
}
case_09() {  # a file size limit: exit 4 naming the file, status failed
  err=$( (ulimit -f 200; "$Q" "$root/experiments/smoke/poms.toml" -o "$work/c09" -q --workers 1 --set experiment.loops=30) 2>&1) \
    && got=0 || got=$?
  [ $got -eq 4 ] || { echo "exit $got: $err"; return 1; }
  grep -q "File too large" <<< "$err" && [ "$(grep -c . <<< "$err")" -eq 1 ]
  grep -q "^failed: cannot write .*File too large" "$work"/c09/*/*/status
}
case_10() {  # a newline in -o: bad input, one line
  refused "output.dir contains a control character \(.*\\\\n.*\)" "$Q" "$exp" -o "$work/c10"$'\n'"x"
}
case_11() {  # a listing that cannot be written
  for what in --list "--describe iso" "--describe experiment"; do
    out=$( ( "$Q" $what > /dev/full ) 2>&1) && got=0 || got=$?
    [ $got -eq 4 ] || { echo "$what > /dev/full: exit $got: $out"; return 1; }
    grep -q "cannot write to standard output: No space left on device" <<< "$out" || { echo "$what: $out"; return 1; }
  done
}
case_12() {  # hostile libraries on the plugin path: rejected by name, never fatal
  out=$("$Q" --list --plugin-path "$plugins/hostile") || { echo "--list failed"; return 1; }
  for lib in ctor_exit:"ended the process while being loaded \(exit\(0\)" ctor_segv:"crashed while being loaded" \
             null_entry:"its entry symbol 'qd_plugin_entry_v1' is null" bad_components:"crashed while being loaded"; do
    grep -Eq "qd_${lib%%:*}\.so: ${lib#*:}" <<< "$out" || { echo "--list does not name qd_${lib%%:*}.so: $out"; return 1; }
  done
  grep -q "^  iso " <<< "$out" && grep -q "^  misspelt " <<< "$out"
  d=$(full_run c12 --plugin-path "$plugins/hostile")
  same_results "$(reference ref)" "$d"
  # A run maps the libraries of its components and no other.
  "$Q" "$exp" -o "$work/c12-maps" -q --workers 1 "${long[@]}" --plugin-path "$plugins/hostile" & pid=$!
  for _ in $(seq 1 3000); do ls "$work"/c12-maps/*/*/checkpoint.bin > /dev/null 2>&1 && break; sleep 0.01; done
  maps=$(grep -o '/qd_[a-z_]*\.so' /proc/$pid/maps | sort -u | tr '\n' ' ')
  kill $pid; wait $pid 2> /dev/null || true
  [ "$maps" = "/qd_arm.so /qd_basic.so " ] || { echo "the run mapped: $maps"; return 1; }
  "$Q" --resume "$d" -q --set experiment.loops=6 --plugin-path "$plugins/hostile" && same_results "$(reference ref6)" "$d"
}
case_13() {  # state files that are symlinks to devices or FIFOs: refused, never read without end
  d=$(stopped_run c13)
  cp -a "$d" "$work/c13.orig"
  mv "$d/checkpoint.bin" "$work/c13.ckpt"; ln -s /dev/zero "$d/checkpoint.bin"
  refused "checkpoint.bin is a symbolic link, not a regular file" "$Q" --resume "$d" -q
  rm "$d/checkpoint.bin"; mv "$work/c13.ckpt" "$d/checkpoint.bin"
  for f in checkpoint.bin dataset.bin archive-state-00000.bin; do
    mv "$d/$f" "$work/c13.file"; mkfifo "$d/$f"
    refused "$f is a FIFO, not a regular file" "$Q" --resume "$d" -q
    refused "$f is a FIFO, not a regular file" "$Q" "$exp" --seeds 7 -o "$work/c13" -q  # a sweep checks first
    rm "$d/$f"; mv "$work/c13.file" "$d/$f"
  done
  mv "$d/status" "$work/c13.status"; mkfifo "$d/status"
  refused "status is a FIFO, not a regular file" "$Q" "$exp" --seeds 7 -o "$work/c13" -q
  rm "$d/status"; mv "$work/c13.status" "$d/status"
  "$Q" --resume "$d" -q && same_results "$(reference ref)" "$d"
}
signal_case() {  # SIGNAL CODE: stops with CODE and a status naming it; --resume finishes it
  local sig=$1 code=$2
  rm -rf "$work/c14-$sig"
  "$Q" "$exp" -o "$work/c14-$sig" -q --workers 1 "${long[@]}" 2> "$work/c14.err" & pid=$!
  for _ in $(seq 1 3000); do ls "$work/c14-$sig"/*/*/checkpoint.bin > /dev/null 2>&1 && break; sleep 0.01; done
  kill -s "$sig" $pid; wait $pid && got=0 || got=$?
  d=$(run_dir "$work/c14-$sig")
  [ $got -eq "$code" ] || { echo "$sig: exit $got: $(cat "$work/c14.err")"; return 1; }
  grep -Eq "^stopped by SIG$sig at loop [0-9]+ iteration [0-9]+; resume with qdrun --resume $d$" "$d/status" \
    || { echo "$sig: status $(cat "$d/status")"; return 1; }
  [ "$(grep -c . "$work/c14.err")" -eq 1 ] || { echo "$sig: $(cat "$work/c14.err")"; return 1; }
  "$Q" --resume "$d" -q && same_results "$(reference reflong)" "$d"
}
case_14() {  # SIGHUP, SIGQUIT, SIGUSR1 handled as SIGTERM; a closed pipe takes only the display
  signal_case HUP 129 && signal_case QUIT 131 && signal_case USR1 138
  "$Q" "$exp" -o "$work/c14-pipe" --workers 1 "${long[@]}" 2>&1 | head -n 1 > /dev/null
  [ "${PIPESTATUS[0]}" -eq 0 ] || { echo "with its pipe closed: exit ${PIPESTATUS[0]}"; return 1; }
  d=$(run_dir "$work/c14-pipe"); is_complete "$d"; same_results "$(reference reflong)" "$d"
}
loop0=(--set experiment.initial_samples=60000 --set experiment.loops=3)
stop_in_loop_0() {  # ARGS...: starts a run with a long loop 0 and stops it there with SIGTERM
  "$Q" "$@" -q --workers 1 "${loop0[@]}" & pid=$!
  for _ in $(seq 1 3000); do grep -qx running "$work"/c15/*/*/status 2> /dev/null && break; sleep 0.01; done
  sleep 0.2
  kill -TERM $pid; wait $pid && got=0 || got=$?
  [ $got -eq 143 ] || { echo "exit $got, expected 143 (loop 0 too short on this machine?)"; return 1; }
}
case_15() {  # SIGTERM in loop 0: one answer (resume, or the same command, starts it again)
  ref15=$(full_run c15ref "${loop0[@]}")
  stop_in_loop_0 "$exp" -o "$work/c15"
  d=$(run_dir "$work/c15")
  grep -Eq "^stopped by SIGTERM at loop 0 iteration 0; resume with qdrun --resume $d \(nothing was checkpointed yet: it starts again from loop 0\)$" "$d/status" \
    || { echo "status: $(cat "$d/status")"; return 1; }
  expect 0 "started again from loop 0" "$Q" --resume "$d" --workers 1
  is_complete "$d"; same_results "$ref15" "$d"
  rm -rf "$work/c15"
  stop_in_loop_0 "$exp" -o "$work/c15"
  expect 0 "started again from loop 0" "$Q" "$exp" -o "$work/c15" --workers 1 "${loop0[@]}"
  d=$(run_dir "$work/c15"); is_complete "$d"; same_results "$ref15" "$d"
}
case_16() {  # checkpoint.bin deleted from a run with results: the missing file is named
  d=$(stopped_run c16)
  rm "$d/checkpoint.bin"
  refused "checkpoint.bin is missing, but the run has results \(.*metrics.csv holds loops up to 1" "$Q" --resume "$d" -q
  refused "holds results but no checkpoint" "$Q" "$exp" -o "$work/c16" -q --workers 1 --stop-after-loop 1
  refused "holds results but no checkpoint" "$Q" "$exp" --seeds 7 -o "$work/c16" -q
  grep -q "^0,0," "$d/metrics.csv"  # nothing was removed
}
case_17() {  # numbers in messages and config.toml: shortest exact form, no contradiction
  refused "experiment.seed = 9000000000000001 is out of range \[0, 9000000000000000\]" "$Q" "$exp" -o "$work/c17" --seed 9000000000000001
  printf 'include = "%s"\n[mutator]\nsigma = inf\n' "$exp" > "$work/c17-inf.toml"
  refused "mutator.sigma = inf is not a finite number \(range \[0, inf\)\)" "$Q" "$work/c17-inf.toml" -o "$work/c17"
  d=$(stopped_run c17 --set mutator.sigma=0.05 --set environment.dt=0.1)
  grep -qx "sigma = 0.05" "$d/config.toml" && grep -qx "dt = 0.1" "$d/config.toml" || { cat "$d/config.toml"; return 1; }
  refused "mutator.sigma is 0.2 in config.toml \(or --set\) but the run was made with 0.05;" "$Q" --resume "$d" -q --set mutator.sigma=0.2
}
case_18() {  # messages that name what they are about
  refused "^qdrun: error: --set foo.bar=1: unknown table 'foo'" "$Q" "$exp" -o "$work/c18" --set foo.bar=1
  refused "^qdrun: error: --cell -1: a cell index is >= 0" "$Q" --replay "$(reference ref)" --cell -1
  refused "^qdrun: error: component 'misspelt' \(.*qd_misspelt.so\) reads the parameter 'sigmaa', which it does not declare" \
    "$Q" "$exp" -o "$work/c18" --plugin-path "$plugins/hostile" --set mutator.type=misspelt
}
case_19() {  # a rename at resume is refused, and the sweep sees the run as its own
  d=$(stopped_run c19)
  refused "experiment.name is .*renamed.* \(the run directory is named after experiment.name\)" \
    "$Q" --resume "$d" -q --set experiment.name=renamed
  "$Q" "$exp" --seeds 7 -o "$work/c19" > "$work/c19.out" || { cat "$work/c19.out"; return 1; }
  grep -q "resume: was 'stopped after loop 1" "$work/c19.out" && is_complete "$d" && same_results "$(reference ref)" "$d"
}
case_20() {  # the environment thread-safety check finds a shared Policy every time
  [ -x "$unit_tests" ] || { echo "no $unit_tests"; return 1; }
  "$unit_tests" --gtest_filter='Conformance.*' --gtest_repeat=3 --gtest_brief=1
}
for n in $(seq -w 1 20); do
  title=$(grep -m1 "^case_$n() {" "$0" | sed 's/.*# //')
  verdict "case $n: $title" "case_$n"
done

# ---- Further hostile conditions -----------------------------------------------------------------
extra_01() {  # a symlink planted as status.tmp (or checkpoint.bin.tmp) is never written through
  d=$(stopped_run x01)
  echo "victim" > "$work/x01.victim"
  ln -s "$work/x01.victim" "$d/status.tmp"; ln -s "$work/x01.victim" "$d/checkpoint.bin.tmp"
  "$Q" --resume "$d" -q
  [ "$(cat "$work/x01.victim")" = victim ] || { echo "the victim was overwritten"; return 1; }
  is_complete "$d"; same_results "$(reference ref)" "$d"
}
extra_02() {  # metrics.csv a symlink to another run's: refused, the other run untouched
  a=$(full_run x02a); d=$(stopped_run x02)
  md5sum "$a/metrics.csv" > "$work/x02.sum"
  rm "$d/metrics.csv"; ln -s "$a/metrics.csv" "$d/metrics.csv"
  refused "metrics.csv is a symbolic link, not a regular file" "$Q" --resume "$d" -q
  md5sum -c --quiet "$work/x02.sum"
}
extra_03() {  # a run directory that is not writable (as an unprivileged user)
  [ "$(id -u)" -eq 0 ] && command -v setpriv > /dev/null || { echo "needs root and setpriv: checked as writable"; }
  d=$(stopped_run x03)
  chmod -R a+rwX "$work/x03"; chmod a-w "$d"; chmod a+x "$work"
  if [ "$(id -u)" -eq 0 ]; then
    setpriv --reuid=65534 --regid=65534 --clear-groups test -x "$Q" || { echo "nobody cannot run $Q (private parent)"; chmod u+w "$d"; return 0; }
    refused "the run directory .* is not writable" setpriv --reuid=65534 --regid=65534 --clear-groups "$Q" --resume "$d" -q
  else
    refused "the run directory .* is not writable" "$Q" --resume "$d" -q
  fi
  chmod u+w "$d"
}
extra_04() {  # a log replaced by a directory
  d=$(stopped_run x04)
  mv "$d/training.csv" "$work/x04.csv"; mkdir "$d/training.csv"
  refused "training.csv is a directory, not a regular file" "$Q" --resume "$d" -q
}
extra_05() {  # the lock replaced by a FIFO: nothing blocks, the run goes on
  d=$(stopped_run x05)
  rm "$d/lock"; mkfifo "$d/lock"
  timeout 60 "$Q" --resume "$d" -q || { echo "resume with a FIFO lock failed"; return 1; }
  is_complete "$d"; same_results "$(reference ref)" "$d"
}
extra_06() {  # a sweep whose run log is a FIFO: refused before anything starts
  d=$(stopped_run x06)
  mkfifo "$d/qdrun.log"
  refused "qdrun.log is a FIFO, not a regular file" "$Q" "$exp" --seeds 7 -o "$work/x06" -q
  grep -q "^stopped after loop 1" "$d/status"
}
extra_07() {  # experiment files that are FIFOs, devices or huge
  mkfifo "$work/x07.toml"
  refused "x07.toml: not a regular file" "$Q" "$work/x07.toml" -o "$work/x07"
  refused "/dev/zero: not a regular file" "$Q" /dev/zero -o "$work/x07"
  head -c 17000000 /dev/zero | tr '\0' '#' > "$work/x07-huge.toml"
  refused "larger than any experiment file" "$Q" "$work/x07-huge.toml" -o "$work/x07"
  : > "$work/x07-empty.toml"
  refused "\[environment\] with a type is required" "$Q" "$work/x07-empty.toml" -o "$work/x07"
}
extra_08() {  # absurd --workers and --jobs: refused, not a fork bomb
  refused "--workers 100000 is out of range \[0, 4096\]" "$Q" "$exp" -o "$work/x08" --workers 100000
  refused "--jobs 100000 is out of range" "$Q" "$exp" --seeds 1,2 -o "$work/x08" --jobs 100000
  refused "--workers -3 is out of range" "$Q" "$exp" -o "$work/x08" --workers -3
}
extra_09() {  # a quote in --backend (TOML injection)
  refused "--backend threads\"x: evaluation.backend = \"threads\"x\" is not one of" "$Q" "$exp" -o "$work/x09" --backend 'threads"x'
}
extra_10() {  # a CPU time limit (ulimit -S -t): stopped by SIGXCPU as by SIGTERM, resumable
  err=$( (ulimit -S -t 2; "$Q" "$exp" -o "$work/x10" -q --workers 1 --backend threads --set experiment.loops=200 \
          --set experiment.iterations=2000) 2>&1) && got=0 || got=$?
  d=$(run_dir "$work/x10")
  [ $got -eq 152 ] || { echo "exit $got: $err"; return 1; }
  grep -Eq "^stopped by SIGXCPU \(CPU time limit\) at loop [0-9]+ iteration [0-9]+; resume with qdrun --resume $d$" \
    "$d/status" || { echo "status: $(cat "$d/status")"; return 1; }
}
extra_11() {  # real-time and SIGUSR2 signals: handled, never a silent death
  for sig in USR2 RTMIN+3; do
    rm -rf "$work/x11"
    "$Q" "$exp" -o "$work/x11" -q --workers 1 "${long[@]}" 2> /dev/null & pid=$!
    for _ in $(seq 1 3000); do ls "$work"/x11/*/*/checkpoint.bin > /dev/null 2>&1 && break; sleep 0.01; done
    kill -s "$sig" $pid; wait $pid && got=0 || got=$?
    d=$(run_dir "$work/x11")
    [ $got -gt 128 ] && grep -q "^stopped by SIG" "$d/status" || { echo "$sig: exit $got, status $(cat "$d/status")"; return 1; }
    "$Q" --resume "$d" -q && same_results "$(reference reflong)" "$d"
  done
}
extra_12() {  # SIGHUP ignored by the launcher (nohup): the run goes on to the end
  (trap '' HUP; exec "$Q" "$exp" -o "$work/x12" -q --workers 1 "${long[@]}") & pid=$!
  for _ in $(seq 1 3000); do ls "$work"/x12/*/*/checkpoint.bin > /dev/null 2>&1 && break; sleep 0.01; done
  kill -HUP $pid; wait $pid || { echo "exit $? under nohup"; return 1; }
  d=$(run_dir "$work/x12"); is_complete "$d"; same_results "$(reference reflong)" "$d"
}
extra_13() {  # QD_PLUGIN_PATH naming a missing directory: said once, the run goes on
  expect 0 "warning: plugin directory /nowhere/plugins \(QD_PLUGIN_PATH\) does not exist" \
    env QD_PLUGIN_PATH=/nowhere/plugins "$Q" "$exp" -o "$work/x13" --workers 1
}
extra_14() {  # control characters in experiment.name
  refused "experiment.name contains a control character" "$Q" "$exp" -o "$work/x14" --set experiment.name=$'a\tb'
}
extra_15() {  # an archive-state file that is a symlink to a random device
  d=$(stopped_run x15)
  f=$(ls "$d"/archive-state-*.bin | head -n 1); rm "$f"; ln -s /dev/urandom "$f"
  refused "$(basename "$f") is a symbolic link, not a regular file" "$Q" --resume "$d" -q
}
extra_16() {  # the snapshot directory is a symlink out of the run: refused, nothing written there
  mkdir -p "$work/x16-elsewhere" "$work/x16/smoke-iso/seed-7"
  ln -s "$work/x16-elsewhere" "$work/x16/smoke-iso/seed-7/archive"
  refused "archive is not a directory of the run" "$Q" "$exp" -o "$work/x16" -q --workers 1 --set output.snapshot_every=1
  [ -z "$(ls "$work/x16-elsewhere")" ] || { echo "snapshots written through the symlink"; return 1; }
}
extra_17() {  # replay of a run whose archive.csv is a FIFO: refused, no hang
  d=$(full_run x17)
  mv "$d/archive.csv" "$work/x17.csv"; mkfifo "$d/archive.csv"
  refused "archive.csv is a FIFO, not a regular file" "$Q" --replay "$d" --all --traces "$work/x17-traces.csv"
}
extra_18() {  # config.toml of a run replaced by a FIFO: refused, no hang
  d=$(stopped_run x18)
  mv "$d/config.toml" "$work/x18.toml"; mkfifo "$d/config.toml"
  refused "config.toml: not a regular file" "$Q" --resume "$d" -q
}
extra_19() {  # binary junk appended to metrics.csv after the checkpoint: cut away, result exact
  d=$(stopped_run x19)
  head -c 300 /dev/urandom >> "$d/metrics.csv"
  "$Q" --resume "$d" -q && same_results "$(reference ref)" "$d"
}
extra_20() {  # the lock is a directory: refused by name
  d=$(stopped_run x20)
  rm "$d/lock"; mkdir "$d/lock"
  refused "lock is a directory, not qdrun's lock file" "$Q" --resume "$d" -q
}
extra_21() {  # empty option values
  refused "--output needs a value" "$Q" "$exp" -o ""
  refused "--describe needs a value" "$Q" --describe ""
  refused "--resume needs a value" "$Q" --resume ""
}
sweep_stopped_by() {  # SIGNAL CODE NUMBER: a sweep of two runs stopped by SIGNAL; the runs stop as qdrun alone does
  local sig=$1 code=$2 number=$3 out=$work/x-sweep-$1
  "$Q" "$exp" "$root/experiments/smoke/uniform.toml" -o "$out" --workers 1 --jobs 2 "${long[@]}" > "$out.out" 2>&1 & pid=$!
  for _ in $(seq 1 3000); do [ "$(ls "$out"/*/*/checkpoint.bin 2> /dev/null | wc -l)" -ge 2 ] && break; sleep 0.01; done
  kill -s "$sig" $pid; wait $pid && got=0 || got=$?
  [ $got -eq "$code" ] || { echo "exit $got: $(cat "$out.out")"; return 1; }
  grep -q "^sweep: stopped by signal $number" "$out.out" || { cat "$out.out"; return 1; }
  for s in "$out"/*/*/status; do grep -q "^stopped by SIG$sig at loop" "$s" || { echo "$s: $(cat "$s")"; return 1; }; done
  "$Q" "$exp" "$root/experiments/smoke/uniform.toml" -o "$out" --workers 1 --jobs 2 "${long[@]}" > "$out.out"
  same_results "$(reference reflong)" "$(ls -d "$out"/smoke-iso/seed-*)"
}
extra_22() {  # a sweep stopped by SIGTERM: its runs stop as qdrun does alone, the sweep says so
  sweep_stopped_by TERM 143 15
}
extra_23() {  # stdout of a sweep's plan is a full disk: exit 4, not success
  out=$( ( "$Q" "$exp" --seeds 1,2 -o "$work/x23" --dry-run > /dev/full ) 2>&1) && got=0 || got=$?
  [ $got -eq 4 ] || { echo "exit $got: $out"; return 1; }
}
extra_24() {  # the run directory removed while the run goes on: a failure naming a file, not success
  "$Q" "$exp" -o "$work/x24" -q --workers 1 "${long[@]}" 2> "$work/x24.err" & pid=$!
  for _ in $(seq 1 3000); do ls "$work"/x24/*/*/checkpoint.bin > /dev/null 2>&1 && break; sleep 0.01; done
  mv "$work/x24" "$work/x24-gone"
  wait $pid && got=0 || got=$?
  [ $got -eq 4 ] || { echo "exit $got: $(cat "$work/x24.err")"; return 1; }
  grep -q "seed-7/" "$work/x24.err"
}
extra_25() {  # a library whose constructor never returns: left out after the probe's 20 s
  out=$(timeout 90 "$Q" --list --plugin-path "$plugins/hostile_hang") || { echo "--list with a hanging library failed"; return 1; }
  grep -q "qd_ctor_hang.so: did not finish loading within 20 s" <<< "$out"
  grep -q "^  iso " <<< "$out"
}
extra_26() {  # SIGCHLD ignored by the launcher: qdrun still knows how its children end
  ignoring() { python3 -c "import signal, os, sys; signal.signal(signal.SIGCHLD, signal.SIG_IGN); os.execv(sys.argv[1], sys.argv[1:])" "$@"; }
  ignoring "$Q" "$exp" "$root/experiments/smoke/uniform.toml" -o "$work/x26" --workers 1 --jobs 2 > "$work/x26.out"
  grep -q "^sweep: 2 runs: 2 finished" "$work/x26.out" || { cat "$work/x26.out"; return 1; }
  out=$(ignoring "$Q" --list --plugin-path "$plugins/hostile") && grep -q "qd_ctor_segv.so: crashed while being loaded" <<< "$out"
}
extra_27() {  # crash signals blocked by the launcher: a crash is still reported
  fault_toml segfault > "$work/x27.toml"
  (exec python3 -c "import signal, os, sys; signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGSEGV, signal.SIGABRT]); os.execv(sys.argv[1], sys.argv[1:])" \
     "$Q" "$work/x27.toml" --plugin-path "$plugins/fault" -q --backend threads --workers 2 -o "$work/x27" 2> "$work/x27.err") \
    && got=0 || got=$?
  [ $got -eq 139 ] && grep -q "^qdrun: failed: SIGSEGV (segmentation fault) in rollout()" "$work/x27.err" \
    || { echo "exit $got: $(cat "$work/x27.err")"; return 1; }
}
extra_28() {  # an experiment file that is a symlink loop
  ln -s "$work/x28.toml" "$work/x28.toml"
  refused "x28.toml: cannot read the experiment file: Too many levels of symbolic links" "$Q" "$work/x28.toml" -o "$work/x28"
}
extra_29() {  # the same run resumed through a symlink to its directory while it runs: refused
  d=$(stopped_run x29 "${long[@]}")
  ln -s "$d" "$work/x29-link"
  "$Q" --resume "$d" -q --workers 1 & first=$!
  wait_for_line "$d/lock" "^pid $first " $first
  refused "is in use by qdrun pid $first" "$Q" --resume "$work/x29-link" -q --workers 1
  wait $first && is_complete "$d"
}
extra_30() {  # the reader of a sweep's lines goes away: the runs go on, the lost lines are reported
  { "$Q" "$exp" --seeds 1,2 -o "$work/x30" --workers 1 --jobs 2 "${long[@]}" 2> "$work/x30.err" | head -n 1 > /dev/null; } \
    && got=0 || got=$?  # (pipefail: qdrun's status)
  [ "$got" -eq 4 ] && grep -q "cannot write to standard output: Broken pipe" "$work/x30.err" \
    || { echo "exit $got: $(cat "$work/x30.err")"; return 1; }
  for d in "$work"/x30/smoke-iso/seed-*; do is_complete "$d"; done
}
extra_31() {  # a CVT run's grid.toml and centroids.csv: FIFOs, device links, paths out refused; cp -al copies private
  cvt=$root/experiments/smoke/poms-cvt.toml
  "$Q" "$cvt" -o "$work/x31" -q --workers 1 --stop-after-loop 1 > /dev/null
  d=$(run_dir "$work/x31")
  cp -a "$d" "$work/x31.orig"
  for f in grid.toml centroids.csv; do
    mv "$d/$f" "$work/x31.file"; mkfifo "$d/$f"
    refused "$f is a FIFO, not a regular file" "$Q" --resume "$d" -q
    refused "$f is a FIFO, not a regular file" "$Q" --replay "$d" --cell 0
    rm "$d/$f"; ln -s /dev/zero "$d/$f"
    refused "$f is a symbolic link, not a regular file" "$Q" --resume "$d" -q
    rm "$d/$f"; mv "$work/x31.file" "$d/$f"
  done
  sed -i 's|^centroids = .*|centroids = "/dev/zero"|' "$d/grid.toml"
  refused "names the centroids file '/dev/zero', which is no file of the run directory" "$Q" --resume "$d" -q
  cp "$work/x31.orig/grid.toml" "$d/grid.toml"
  diff -r "$work/x31.orig" "$d"  # every refusal left the run as it was
  "$Q" --resume "$d" -q
  (cd "$d" && find . -type f -exec md5sum {} + | sort) > "$work/x31.before"
  cp -al "$work/x31" "$work/x31-copy"
  "$Q" --resume "$(run_dir "$work/x31-copy")" -q --set experiment.loops=6
  (cd "$d" && find . -type f -exec md5sum {} + | sort) > "$work/x31.after"
  diff "$work/x31.before" "$work/x31.after" || { echo "extending the copy changed the original"; return 1; }
  "$Q" "$cvt" -o "$work/x31-ref" -q --workers 1 --set experiment.loops=6 > /dev/null
  same_results "$(run_dir "$work/x31-ref")" "$(run_dir "$work/x31-copy")"
}
extra_32() {  # a sweep stopped by SIGUSR1 (any stop signal, not only SIGTERM): passed on to its runs, said
  sweep_stopped_by USR1 138 10
}
extra_33() {  # a sweep that planned to restart a run finds another qdrun running it: that run's files stay
  "$Q" "$exp" -o "$work/x33" -q --workers 1 "${loop0[@]}" & pid=$!
  for _ in $(seq 1 3000); do grep -qx running "$work"/x33/*/*/status 2> /dev/null && break; sleep 0.01; done
  kill -TERM $pid; wait $pid || true
  d=$(run_dir "$work/x33")
  [ ! -e "$d/checkpoint.bin" ] || { echo "loop 0 was checkpointed already (too short on this machine?)"; return 1; }
  # The sweep plans seed 7 as a restart, and runs seed 8 first; meanwhile seed 7 is resumed by hand.
  "$Q" "$exp" --seeds 8,7 -o "$work/x33" --workers 1 --jobs 1 "${loop0[@]}" > "$work/x33.out" & sweep=$!
  for _ in $(seq 1 3000); do grep -q "start  smoke-iso/seed-8" "$work/x33.out" && break; sleep 0.01; done
  "$Q" --resume "$d" -q --workers 1 & first=$!
  wait $sweep && got=0 || got=$?
  wait $first || { echo "the resumed run failed"; return 1; }
  [ $got -eq 1 ] && grep -q "FAILED smoke-iso/seed-7: .*is in use by qdrun\|already holds a run" "$work/x33.out" \
    || { echo "sweep exit $got: $(cat "$work/x33.out")"; return 1; }
  is_complete "$d"; same_results "$(reference ref0)" "$d"
  [ "$(head -n 1 "$d/metrics.csv" | cut -d, -f1)" = loop ] && [ -e "$d/config.toml" ] && [ -e "$d/provenance.toml" ]
}
extra_34() {  # replay's output named as a device, FIFO or directory: refused, the node left as it was
  d=$(reference ref)
  mkfifo "$work/x34.fifo"; mkdir "$work/x34.dir"
  targets=("$work/x34.fifo" "$work/x34.dir")
  if [ "$(id -u)" -eq 0 ]; then mknod -m 666 "$work/x34.null" c 1 3; targets+=("$work/x34.null"); fi
  for t in "${targets[@]}"; do
    before=$(stat -c %F "$t")
    refused "--traces $t: .* not a regular file" "$Q" --replay "$d" --all --traces "$t" --workers 1
    refused "--svg $t: .* not a regular file" "$Q" --replay "$d" --cell "$(sed -n 2p "$d/archive.csv" | cut -d, -f1)" --svg "$t"
    [ "$(stat -c %F "$t")" = "$before" ] || { echo "$t is now a $(stat -c %F "$t")"; return 1; }
  done
}
extra_35() {  # --seeds out of range, reversed or too many: one line, exit 2
  refused "seed 99999999999999999999 is out of range \[0, 9000000000000000\]" "$Q" "$exp" --seeds 99999999999999999999 -o "$work/x35"
  refused "the range '5-1' goes down" "$Q" "$exp" --seeds 5-1 -o "$work/x35"
  refused "holds 200000 seeds, more than the 100000" "$Q" "$exp" --seeds 1-200000 -o "$work/x35"
  refused "'-3' is not a non-negative integer" "$Q" "$exp" --seeds=-3 -o "$work/x35"
  [ ! -e "$work/x35" ]
}
extra_36() {  # too little address space (ulimit -v): exit 4 naming what failed, never an internal failure
  # The sanitizers' runtime needs both itself (shadow memory; a pipe to probe memory): not testable there.
  [ -z "${ASAN_OPTIONS:-}" ] || { echo "not under the sanitizers"; return 0; }
  for v in $(seq 9000 3000 45000); do
    rm -rf "$work/x36"
    err=$( (ulimit -v $v; "$Q" "$exp" -o "$work/x36" -q --workers 2) 2>&1) && got=0 || got=$?
    case $got in
    127) continue ;;  # the dynamic loader could not map qdrun's libraries: qdrun never ran
    0) is_complete "$(run_dir "$work/x36")" ;;
    4) [ "$(grep -c . <<< "$err")" -eq 1 ] || { echo "ulimit -v $v: $err"; return 1; }
       for s in "$work"/x36/*/*/status; do [ ! -e "$s" ] || ! grep -qx running "$s" || { echo "ulimit -v $v: status running"; return 1; }; done ;;
    *) echo "ulimit -v $v: exit $got: $err"; return 1 ;;
    esac
  done
}
extra_37() {  # a directory where the status or a temporary file goes: exit 2 naming it, the run as it was
  d=$(stopped_run x37)
  cp -a "$d" "$work/x37.orig"
  mv "$d/status" "$work/x37.status"; mkdir "$d/status"
  refused "status is a directory, not a regular file" "$Q" --resume "$d" -q
  rmdir "$d/status"; mv "$work/x37.status" "$d/status"
  mkdir "$d/checkpoint.bin.tmp"
  refused "checkpoint.bin.tmp is a directory, where qdrun writes its temporary file for checkpoint.bin" "$Q" --resume "$d" -q
  grep -q "^failed: .*checkpoint.bin.tmp is a directory" "$d/status"
  rmdir "$d/checkpoint.bin.tmp"
  "$Q" --resume "$d" -q && same_results "$(reference ref)" "$d"
}
extra_38() {  # entries named like plugins that are no files (a dangling symlink, a loop, a FIFO, a directory)
  mkdir "$work/x38"
  ln -s /nowhere/qd_gone.so "$work/x38/qd_gone.so"; ln -s qd_loop.so "$work/x38/qd_loop.so"
  mkfifo "$work/x38/qd_fifo.so"; mkdir "$work/x38/qd_dir.so"
  out=$(timeout 60 "$Q" --list --plugin-path "$work/x38") || { echo "--list failed"; return 1; }
  for what in "qd_gone.so: a symbolic link to nothing" "qd_loop.so: a symbolic link loop" "qd_fifo.so: a FIFO" \
              "qd_dir.so: a directory"; do
    grep -q "$what.*, not a shared library" <<< "$out" || { echo "--list does not say $what: $out"; return 1; }
  done
}
extra_39() {  # an include cycle: named with its files, not followed to a depth limit
  printf 'include = "x39-b.toml"\n' > "$work/x39-a.toml"; printf 'include = "x39-a.toml"\n' > "$work/x39-b.toml"
  refused "x39-a.toml: an include cycle \(.*x39-a.toml -> .*x39-b.toml -> .*x39-a.toml\)" "$Q" "$work/x39-a.toml" -o "$work/x39"
}
extra_40() {  # too few file descriptors (ulimit -n): exit 4 naming the file, and the status says so
  # The sanitizers' runtime needs both itself (shadow memory; a pipe to probe memory): not testable there.
  [ -z "${ASAN_OPTIONS:-}" ] || { echo "not under the sanitizers"; return 0; }
  for n in $(seq 6 16); do
    rm -rf "$work/x40"
    err=$( (ulimit -n $n; "$Q" "$exp" -o "$work/x40" -q --workers 2) 2>&1) && got=0 || got=$?
    case $got in
    0) is_complete "$(run_dir "$work/x40")" ;;
    4) [ "$(grep -c . <<< "$err")" -eq 1 ] && grep -q "Too many open files" <<< "$err" || { echo "ulimit -n $n: $err"; return 1; }
       for s in "$work"/x40/*/*/status; do [ ! -e "$s" ] || grep -q "^failed: .*Too many open files" "$s" || { echo "ulimit -n $n: status $(cat "$s")"; return 1; }; done ;;
    *) echo "ulimit -n $n: exit $got: $err"; return 1 ;;
    esac
  done
}
extra_41() {  # an experiment file edited while its sweep runs: later runs are refused, never run with the edit
  cp "$exp" "$work/x41.toml"
  "$Q" "$work/x41.toml" --seeds 1,2 -o "$work/x41" --workers 1 --jobs 1 "${long[@]}" > "$work/x41.out" & pid=$!
  for _ in $(seq 1 3000); do grep -q "start  smoke-iso/seed-1" "$work/x41.out" && break; sleep 0.01; done
  sed -i 's/^sigma = .*/sigma = 0.3/' "$work/x41.toml"
  wait $pid && got=0 || got=$?
  [ $got -eq 1 ] && grep -q "FAILED smoke-iso/seed-2: cannot start it: .*x41.toml (or a file it includes) changed since the sweep planned this run ('sigma = 0.1' then, 'sigma = 0.3' now)" "$work/x41.out" \
    || { echo "exit $got: $(cat "$work/x41.out")"; return 1; }
  # seed 1 started before the edit: it ran as planned, or, when it read the file after the edit,
  # refused to (the child checks the configuration it read against the plan).
  if grep -q "FAILED smoke-iso/seed-1" "$work/x41.out"; then
    grep -q "changed since the sweep planned this run" "$work/x41/smoke-iso/seed-1/qdrun.log"
  else
    is_complete "$work/x41/smoke-iso/seed-1"
  fi
  ! grep -l "^sigma = 0.3" "$work"/x41/*/*/config.toml || { echo "a run used the edited file"; return 1; }
  refused "x41.toml \(or a file it includes\) changed since the sweep planned this run" \
    "$Q" "$work/x41.toml" --planned-config 00000000 -o "$work/x41-direct"
}
for n in $(seq -w 1 41); do
  title=$(grep -m1 "^extra_$n() {" "$0" | sed 's/.*# //')
  verdict "extra $n: $title" "extra_$n"
done
echo "hostile conditions: $passed passed, $failed failed ($((SECONDS - start)) s)"
[ -z "$only" ] || exit $((failed > 0))

# ---- Random kills ---------------------------------------------------------------------------------
budget=(--set experiment.loops=12 --set experiment.iterations=20)
exp=$root/experiments/smoke/poms.toml
"$Q" "$exp" -o "$work/full" -q --workers 1 "${budget[@]}" || { echo "the reference run failed"; exit 1; }
full=$(run_dir "$work/full")
identical=0 differed=0 no_checkpoint=0
for k in $(seq 1 "$kills"); do
  rm -rf "$work/k"
  "$Q" "$exp" -o "$work/k" -q --workers 1 "${budget[@]}" & pid=$!
  sleep "$(python3 -c "import random; print(random.uniform(0.3, 3.0))")"
  kill -9 $pid 2> /dev/null; wait $pid 2> /dev/null
  dir=$(run_dir "$work/k")
  if grep -qx complete "$dir/status" 2> /dev/null; then identical=$((identical + 1)); continue; fi
  if [ ! -e "$dir/checkpoint.bin" ]; then no_checkpoint=$((no_checkpoint + 1)); continue; fi
  "$Q" --resume "$dir" -q --workers 2 > /dev/null 2>&1
  if same_results "$full" "$dir" > /dev/null 2>&1; then identical=$((identical + 1)); else differed=$((differed + 1)); fi
done
echo "random kills: $kills trials, $identical identical resumes, $no_checkpoint killed before the first checkpoint, $differed different"

# ---- Bit flips ------------------------------------------------------------------------------------
"$Q" "$exp" -o "$work/stop" -q --workers 1 "${budget[@]}" --stop-after-loop 5 || exit 1
stop=$(run_dir "$work/stop")
cp -a "$stop" "$work/pristine"
trials=0 refused=0 same=0 silent=0
for f in checkpoint.bin dataset.bin $(cd "$stop" && ls archive-state-*.bin); do
  size=$(stat -c %s "$stop/$f")
  for i in $(seq 0 $((flips - 1))); do
    rm -rf "$stop" && cp -a "$work/pristine" "$stop"
    at=$(( (size - 1) * i / (flips - 1) ))
    python3 -c "import sys; p, i, b = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]); d = bytearray(open(p, 'rb').read()); d[i] ^= 1 << b; open(p, 'wb').write(d)" "$stop/$f" "$at" $((i % 8))
    trials=$((trials + 1))
    "$Q" --resume "$stop" -q --workers 1 > /dev/null 2>&1; code=$?
    if [ $code -eq 2 ]; then refused=$((refused + 1))
    elif [ $code -eq 0 ] && same_results "$full" "$stop" > /dev/null 2>&1; then same=$((same + 1))
    else silent=$((silent + 1)); echo "  silent change: $f byte $at bit $((i % 8)) (exit $code)"; fi
  done
done
echo "bit flips: $trials trials, $refused refused corruptions, $same identical resumes, $silent silent changes"
echo "total: $passed of $((passed + failed)) hostile conditions passed; kills $differed different, bit flips $silent silent; $((SECONDS - start)) s"
[ "$failed" -eq 0 ] && [ "$differed" -eq 0 ] && [ "$silent" -eq 0 ]
