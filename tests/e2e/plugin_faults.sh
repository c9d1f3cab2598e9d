#!/usr/bin/env bash
# A misbehaving plugin never crashes, hangs or fakes success silently (issue 20). Runs the fault
# injection plugin (tests/plugins/fault.cpp) with one fault at loop 2, iteration 1, offspring 4
# (after the checkpoint of loop 1) and checks what qdrun does:
#  * a rollout that crashes, aborts, exits (code 0 or 1), hangs or throws, a cell outside the grid,
#    a mutator's or representation's broken output: exit 3, one line naming the component, its
#    library and where it happened, status "failed: ...", the checkpoint kept, the faulty
#    offspring saved (rollout faults), and --resume with the fault switched off
#    (QD_FAULT_DISABLE=1, the stand-in for a fixed plugin) equal to a run that never had it;
#  * a non-finite fitness or descriptor value: the run completes, that evaluation is counted
#    invalid (one more than without the fault), one warning names the component, and no nan or
#    inf reaches archive.csv.
#   plugin_faults.sh QDRUN PLUGIN_DIR OUT CASE BACKEND
# BACKEND: serial (the default: one supervised worker process), processes (2 worker processes),
# threads (2 threads in qdrun's process), inprocess (--backend threads --workers 1), mpi (mpirun
# -np 2: each rank evaluates in a supervised worker process of its own; every run of the case,
# the --resume included, under mpirun), mpi1 (mpirun -np 1: rank 0 evaluates every offspring,
# so its own worker process meets the fault). On the unsupervised threads and inprocess backends a
# rollout that crashes or exits takes qdrun's own process with it: qdrun's guards then leave status
# "failed: SIGSEGV in rollout() of ..." (or "exit(0) called in ..."), one line on stderr and the
# signal's exit status (139, 134) or exit code 3; a hang there cannot be timed out (documented), so
# that case is skipped (exit 77). mutator-segfault, mutator-exit0 and mutator-quick-exit crash or
# exit in mutate(), which runs in qdrun's own process under every backend (not run under mpirun,
# which reports a dead rank 0 in its own words).
source "$(dirname "$0")/lib.sh"
qdrun=$1 plugins=$2 out=$3 case=$4 backend=$5
launch=()
# Under the sanitizers (scripts/test.sh --sanitize) a deliberate segfault or exit() would otherwise
# end in AddressSanitizer's report or a leak report instead of the fault itself.
[ -z "${ASAN_OPTIONS:-}" ] || export ASAN_OPTIONS="$ASAN_OPTIONS:handle_segv=0:detect_leaks=0"
rm -rf "$out"
mkdir -p "$out"

case $backend in
serial) backend_args=(--workers 1) ;;
processes) backend_args=(--workers 2 --backend processes) ;;
threads) backend_args=(--workers 2 --backend threads) ;;
inprocess) backend_args=(--workers 1 --backend threads) ;;
mpi) backend_args=() launch=(mpi 2); mpi_sanitizer_env ;;
mpi1) backend_args=() launch=(mpi 1); mpi_sanitizer_env ;;
*) echo "unknown backend $backend"; exit 2 ;;
esac

env_fault=none mutator='type = "iso"
sigma = 0.1' representation='type = "none"'
case $case in
segfault | abort | exit0 | exit1 | hang)
  if [ $case = hang ] && { [ "$backend" = threads ] || [ "$backend" = inprocess ]; }; then
    echo "SKIPPED: $backend is unsupervised and cannot time out a rollout"; exit 77
  fi
  env_fault=$case ;;
throw | nan-fitness | inf-descriptor | nan-descriptor | cell-out-of-range) env_fault=$case ;;
mutator-segfault | mutator-exit0 | mutator-quick-exit)
  if [ "$backend" = mpi ] || [ "$backend" = mpi1 ]; then echo "SKIPPED: mpirun reports a dead rank 0 itself"; exit 77; fi
  mutator="type = \"fault-mutator\"
fault = \"${case#mutator-}\"
fault_loop = 2
fault_iteration = 1" ;;
mutator-*) mutator="type = \"fault-mutator\"
fault = \"${case#mutator-}\"
fault_loop = 2
fault_iteration = 1" ;;
repr-*) representation="type = \"fault-linear\"
fault = \"${case#repr-}\"
fault_loop = 2" ;;
*) echo "unknown case $case"; exit 2 ;;
esac

cat > "$out/fault.toml" <<TOML
[experiment]
name = "fault"
seed = 3
loops = 4
iterations = 3
batch = 10
initial_samples = 30

[environment]
type = "fault-arm"
fault = "$env_fault"
fault_loop = 2
fault_iteration = 1
fault_offspring = 4

[policy]
hidden = [4]

[representation]
$representation

[mutator]
$mutator

[evaluation]
timeout_seconds = 2
TOML

run() { "${launch[@]}" "$qdrun" "$out/fault.toml" --plugin-path "$plugins" -q "${backend_args[@]}" "$@"; }

# The run that never had the fault.
QD_FAULT_DISABLE=1 run -o "$out/clean"
clean=$(run_dir "$out/clean")
grep -qx complete "$clean/status"

set +e
if [ ${#launch[@]} -eq 0 ]; then
  # exec: the subshell becomes qdrun, so the shell's "Segmentation fault" report of its death goes
  # to this script's stderr, not into the file that must hold qdrun's one line.
  (exec "$qdrun" "$out/fault.toml" --plugin-path "$plugins" -q "${backend_args[@]}" -o "$out/faulty" 2> "$out/err")
else
  run -o "$out/faulty" 2> "$out/err"
fi
got=$?
set -e
dir=$(run_dir "$out/faulty")
lib='\([^)]*qd_fault\.so\)'
where='loop 2, iteration 1'

case $case in
nan-fitness | inf-descriptor | nan-descriptor)
  [ "$got" -eq 0 ] || { echo "exit code $got, expected 0: $(cat "$out/err")"; exit 1; }
  grep -qx complete "$dir/status" || { echo "status: $(cat "$dir/status")"; exit 1; }
  case $case in
  nan-fitness) regex="warning: environment 'fault-arm' $lib returned fitness nan for offspring 4 of $where" ;;
  inf-descriptor) regex="warning: descriptor 'fault-endpoint' $lib returned descriptor value inf \(dimension 1\) for offspring 4 of $where" ;;
  nan-descriptor) regex="warning: descriptor 'fault-endpoint' $lib returned descriptor value nan \(dimension 0\) for offspring 4 of $where" ;;
  esac
  grep -Eq -- "$regex" "$out/err" || { echo "stderr does not match /$regex/: $(cat "$out/err")"; exit 1; }
  [ "$(grep -c . "$out/err")" -eq 1 ] || { echo "expected one warning: $(cat "$out/err")"; exit 1; }
  if grep -Eiq '(^|,)[+-]?(nan|inf)' "$dir/archive.csv"; then echo "nan or inf in archive.csv"; exit 1; fi
  # Exactly the faulty evaluation is counted invalid: one more than the clean run, in that row.
  invalid() {
    awk -F, 'NR==1{for(i=1;i<=NF;i++) col[$i]=i; next} $col["loop"]==2 && $col["iteration"]==1 {print $col["invalid"]}' "$1/metrics.csv"
  }
  a=$(invalid "$clean") b=$(invalid "$dir")
  [ -n "$a" ] && [ "$b" -eq $((a + 1)) ] || { echo "invalid at $where: $b with the fault, $a without"; exit 1; }
  echo "plugin fault $case ($backend) ok"
  exit 0
  ;;
segfault) regex="worker process [0-9]+ \(pid [0-9]+\) was killed by signal 11 \(Segmentation fault\) in rollout\(\) of environment 'fault-arm' $lib" ;;
abort) regex="worker process [0-9]+ \(pid [0-9]+\) was killed by signal 6 \(Aborted\) in rollout\(\) of environment 'fault-arm' $lib" ;;
exit0 | exit1) regex="worker process [0-9]+ \(pid [0-9]+\) exited with code ${case#exit} in rollout\(\) of environment 'fault-arm' $lib" ;;
hang) regex="worker process [0-9]+ \(pid [0-9]+\) made no progress for 2 s \(\[evaluation\] timeout_seconds\) in rollout\(\) of environment 'fault-arm' $lib" ;;
throw) regex="^qdrun: error: environment 'fault-arm' $lib threw from rollout\(\): deliberate fault in rollout\(\)" ;;
cell-out-of-range) regex="^qdrun: error: descriptor 'fault-endpoint' $lib returned cell 400, outside its grid's \[0, 400\)" ;;
mutator-short) regex="^qdrun: error: mutator 'fault-mutator' $lib returned offspring of shape 9 x [0-9]+ in $where, expected 10 x" ;;
mutator-nan) regex="^qdrun: error: mutator 'fault-mutator' $lib returned parameter nan \(offspring 0, parameter 0\) in $where" ;;
mutator-throw) regex="^qdrun: error: mutator 'fault-mutator' $lib threw from mutate\(\): deliberate fault in mutate\(\)" ;;
repr-nan-decode) regex="^qdrun: error: representation 'fault-linear' $lib decode\(\) returned nan \(row 0, column 0\)" ;;
repr-short-encode) regex="^qdrun: error: representation 'fault-linear' $lib encode\(\) returned 9 x 2, expected 10 x 2" ;;
esac
# Crashes and exits in qdrun's own process: its guards name the call, the component and its library.
want=3
own="$lib, after loop 2 iteration 0; the last checkpoint is intact: fix the cause and qdrun --resume $dir\$"
in_process=false
case $backend in threads | inprocess) in_process=true ;; esac
case $case in
segfault | abort | exit0 | exit1)
  if $in_process; then
    case $case in
    segfault) regex="^qdrun: failed: SIGSEGV \(segmentation fault\) in rollout\(\) of environment 'fault-arm' $own" want=139 ;;
    abort) regex="^qdrun: failed: SIGABRT \(abort\) in rollout\(\) of environment 'fault-arm' $own" want=134 ;;
    *) regex="^qdrun: failed: exit\(${case#exit}\) called in rollout\(\) of environment 'fault-arm' $own" ;;
    esac
  fi ;;
mutator-segfault) regex="^qdrun: failed: SIGSEGV \(segmentation fault\) in mutate\(\) of mutator 'fault-mutator' $own" want=139 ;;
mutator-exit0) regex="^qdrun: failed: exit\(0\) called in mutate\(\) of mutator 'fault-mutator' $own" ;;
mutator-quick-exit) regex="^qdrun: failed: quick_exit\(\) called in mutate\(\) of mutator 'fault-mutator' $own" ;;
esac
# Under MPI a dead or hung worker process is named with its rank and host.
case $case in
segfault | abort | exit0 | exit1 | hang)
  case $backend in
  mpi) regex="MPI rank [0-9]+ on [^ ]+: $regex" ;;
  mpi1) regex="MPI rank 0 on [^ ]+: $regex" ;;
  esac ;;
esac
check_fault_offspring() {
  regex="$regex.*\(offspring 4 of $where; parameters and episode seed in $dir/fault-offspring.csv\)"
  [ "$(sed -n 2p "$dir/fault-offspring.csv" | cut -d, -f1-3)" = "2,1,4" ] \
    || { echo "fault-offspring.csv: $(cat "$dir/fault-offspring.csv" 2>&1)"; exit 1; }
  [ "$(head -n 1 "$dir/fault-offspring.csv" | tr ',' '\n' | grep -c '^solution_')" -eq \
    "$(sed -n 2p "$dir/fault-offspring.csv" | tr ',' '\n' | tail -n +5 | grep -c .)" ] \
    || { echo "fault-offspring.csv: header and row differ"; exit 1; }
}
# Rollout and descriptor faults name the offspring and save it for the plugin's author (not a crash
# in qdrun's own process: its signal handler only writes prepared text).
case $case in
mutator-* | repr-*) ;;
segfault | abort | exit0 | exit1) $in_process || check_fault_offspring ;;
*) check_fault_offspring ;;
esac
expect_failed_run "$got" $want "$out/err" "$regex" "$dir"
grep -Eq "^failed: .*'fault-[a-z]+' $lib" "$dir/status" || { echo "status: $(cat "$dir/status")"; exit 1; }
QD_FAULT_DISABLE=1 "${launch[@]}" "$qdrun" --resume "$dir" --plugin-path "$plugins" -q
grep -qx complete "$dir/status"
same_results "$clean" "$dir"
echo "plugin fault $case ($backend) ok"
