#!/usr/bin/env bash
# Installs qd into a fresh prefix, builds the README's out-of-tree plugin (examples/half-step, from
# the copy the install carries) against it with find_package(qd) and qd_add_plugin(), runs the
# plugin's own test (the installed conformance checks), checks how both were compiled, and runs the
# plugin through the installed qdrun: a run, its --resume without QD_PLUGIN_PATH, a component swap
# with --set and include, and the plugin built with -D_GLIBCXX_DEBUG refused.
set -euo pipefail
build=$1 src=$2 work=$3
# A sanitizer build's libqd_core needs the sanitizer runtime in every program that links it.
consumer_flags=()
if [ "${4:-}" = sanitize ]; then
  san=-fsanitize=address,undefined
  consumer_flags=(-DCMAKE_CXX_FLAGS=$san -DCMAKE_EXE_LINKER_FLAGS=$san -DCMAKE_MODULE_LINKER_FLAGS=$san)
fi
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work.install.log" 2>&1 || { cat "$work.install.log"; exit 1; }
fail() { echo "FAIL: $*"; exit 1; }
example=$work/prefix/share/qd/examples/half-step
cmp "$example/half_step_test.cpp" "$src/examples/half-step/half_step_test.cpp" || fail "the install carries no example test"
# No build type: the example's CMakeLists.txt is the README's four lines, which set none.
cmake -S "$example" -B "$work/example-build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_EXPORT_COMPILE_COMMANDS=ON "${consumer_flags[@]}" \
      > "$work.configure.log" 2>&1 || { cat "$work.configure.log"; exit 1; }
cmake --build "$work/example-build" > "$work.build.log" 2>&1 || { cat "$work.build.log"; exit 1; }
test -f "$work/example-build/qd_half_step.so"
# The plugin's own GoogleTest test, which runs qd's installed conformance checks on it.
(cd "$work/example-build" && ctest --output-on-failure) > "$work.ctest.log" 2>&1 || { cat "$work.ctest.log"; exit 1; }
grep -q "100% tests passed" "$work.ctest.log" || { cat "$work.ctest.log"; fail "the example's test did not run"; }

# The core's instruction-set flags are recorded in the package, not forced on every consumer
# target; qd_add_plugin applies them to the plugin, optimised when the project chose no build type,
# and leaves a build type the project chose alone.
targets=$(find "$work/prefix" -name qdTargets.cmake)
arch=$(sed -n 's/^ *QD_ARCH_FLAGS "\(.*\)"$/\1/p' "$targets" | tr ';' ' ')  # a CMake list
grep -q INTERFACE_COMPILE_OPTIONS "$targets" && fail "an installed target exports compile options: $targets"
compile_command() { grep "\"command\":.*/$2\"" "$1/compile_commands.json"; }
for file in half_step.cpp half_step_test.cpp; do  # the plugin, and its test (qd_use_core_flags)
  cmd=$(compile_command "$work/example-build" $file)
  grep -qE -- ' -O[23s]? ' <<< "$cmd" || fail "$file was compiled without optimisation: $cmd"
  # QD_ARCH_FLAGS is a CMake list (-march=x86-64-v4;-mtune=generic): one flag per element.
  for flag in ${arch//;/ }; do grep -q -- " $flag " <<< "$cmd" || fail "$file was compiled without the core's $flag: $cmd"; done
  # Eigen's product blocking must not depend on the CPU's caches in third-party plugins either.
  grep -q -- " -DEIGEN_NO_CPUID " <<< "$cmd" || fail "$file was compiled without EIGEN_NO_CPUID: $cmd"
done
cmake -S "$example" -B "$work/example-debug" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DCMAKE_BUILD_TYPE=Debug "${consumer_flags[@]}" \
      > "$work.configure-debug.log" 2>&1 || { cat "$work.configure-debug.log"; exit 1; }
cmd=$(compile_command "$work/example-debug" half_step.cpp)
grep -qE -- ' -O[1-3s]? ' <<< "$cmd" && fail "a Debug build of the plugin was optimised: $cmd"
grep -q -- ' -g ' <<< "$cmd" || fail "a Debug build of the plugin lost -g: $cmd"
# The installed qdrun finds the installed plugins next to itself and the new one on QD_PLUGIN_PATH,
# and nothing of the build tree it was built in (the prefix lies inside that build tree).
qdrun=$work/prefix/bin/qdrun
smoke=$(cd "$src/experiments/smoke" && pwd)
sed 's/^type = "iso"/type = "half-step"/; /^sigma/d' "$smoke/iso.toml" > "$work/exp.toml"
listing=$(QD_PLUGIN_PATH="$work/example-build" "$qdrun" --list 2> "$work/list.err")
grep -q "half-step" <<< "$listing"
grep -q "poms" <<< "$listing"  # the installed plugins are found next to the installed qdrun
grep -q "$build/lib/qd/plugins" <<< "$listing" && fail "the installed qdrun searches the build tree: $listing"
[ -s "$work/list.err" ] && fail "qdrun --list warned: $(cat "$work/list.err")"
# An unknown component is a one-line error (no list of unrelated libraries).
err=$(env -u QD_PLUGIN_PATH "$qdrun" "$work/exp.toml" -o "$work/runs-unknown" --set mutator.type=no-such 2>&1) && fail "an unknown mutator ran"
[ "$(wc -l <<< "$err")" -eq 1 ] || fail "unknown-component error of several lines: $err"
grep -q "unknown mutator 'no-such'" <<< "$err" || fail "unexpected error: $err"
QD_PLUGIN_PATH="$work/example-build" "$qdrun" "$work/exp.toml" -o "$work/runs" -q
grep -qx complete "$work/runs/smoke-iso/seed-7/status"
grep -q "plugin = \"half_step\"" "$work/runs/smoke-iso/seed-7/provenance.toml"

# (a) config.toml records the plugin search path (absolute), so --resume needs no QD_PLUGIN_PATH,
# and continues to the archive of the uninterrupted run.
plugin_dir=$(cd "$work/example-build" && pwd -P)
QD_PLUGIN_PATH="$work/example-build" "$qdrun" "$work/exp.toml" -o "$work/runs-resume" -q --stop-after-loop 1
dir=$work/runs-resume/smoke-iso/seed-7
grep -q "^stopped after loop 1" "$dir/status" || fail "status: $(cat "$dir/status")"
/usr/bin/python3 - "$work/prefix/share/qd" "$dir/config.toml" "$plugin_dir" <<'PY_CHECK' || fail "config.toml does not record the plugin directory"
import sys
sys.path.insert(0, sys.argv[1])  # the installed tools' reader
from qdtools.runs import read_toml
plugins = read_toml(sys.argv[2])["plugins"]
assert plugins == {"search_path": [sys.argv[3]]}, plugins
PY_CHECK
env -u QD_PLUGIN_PATH "$qdrun" --resume "$dir" -q
grep -qx complete "$dir/status"
cmp "$dir/archive.csv" "$work/runs/smoke-iso/seed-7/archive.csv" || fail "the resumed run differs from the uninterrupted one"
# A library that is gone is named, with where the run found it.
QD_PLUGIN_PATH="$work/example-build" "$qdrun" "$work/exp.toml" -o "$work/runs-gone" -q --stop-after-loop 1
mv "$work/example-build" "$work/example-build.away"
err=$(env -u QD_PLUGIN_PATH "$qdrun" --resume "$work/runs-gone/smoke-iso/seed-7" 2>&1) && code=0 || code=$?
mv "$work/example-build.away" "$work/example-build"
[ "$code" -eq 2 ] || fail "resume without the plugin: exit $code: $err"
grep -qF "this run loaded [mutator] 'half-step' from $plugin_dir/qd_half_step.so (plugin half_step 0.0.1), which no longer exists" <<< "$err" \
  || fail "resume without the plugin: $err"

# (b) A component swap through --set over a file with other mutator keys (sigma of iso): the keys
# half-step does not declare are dropped with a note; the same through include.
QD_PLUGIN_PATH="$work/example-build" "$qdrun" "$smoke/iso.toml" --set mutator.type=half-step -o "$work/runs-swap" \
  2> "$work/swap.err" > /dev/null
grep -qF "qdrun: note: [mutator] type = \"half-step\" (--set mutator.type=half-step) replaces \"iso\": dropped sigma ($smoke/iso.toml:" "$work/swap.err" \
  || fail "no note about the dropped key: $(cat "$work/swap.err")"
printf 'include = "%s"\n[experiment]\nname = "swap-include"\n[mutator]\ntype = "half-step"\nstep = 0.25\n' "$smoke/iso.toml" > "$work/swap.toml"
QD_PLUGIN_PATH="$work/example-build" "$qdrun" "$work/swap.toml" -o "$work/runs-swap" -q
for run in smoke-iso:0.5 swap-include:0.25; do
  name=${run%%:*} step=${run#*:}
  grep -qx complete "$work/runs-swap/$name/seed-7/status"
  /usr/bin/python3 - "$work/prefix/share/qd" "$work/runs-swap/$name/seed-7/config.toml" "$step" <<'PY_CHECK' || fail "$name: [mutator] of config.toml"
import sys
sys.path.insert(0, sys.argv[1])
from qdtools.runs import read_toml
mutator = read_toml(sys.argv[2])["mutator"]
assert mutator == {"type": "half-step", "step": float(sys.argv[3])}, mutator
PY_CHECK
done

# (c) The plugin built with -D_GLIBCXX_DEBUG (other std:: container layouts) is refused, the message
# naming both fingerprints.
cmake -S "$example" -B "$work/example-debug-stl" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DBUILD_TESTING=OFF -DCMAKE_CXX_FLAGS=-D_GLIBCXX_DEBUG \
      > "$work.configure-debug-stl.log" 2>&1 || { cat "$work.configure-debug-stl.log"; exit 1; }
cmake --build "$work/example-debug-stl" > "$work.build-debug-stl.log" 2>&1 || { cat "$work.build-debug-stl.log"; exit 1; }
core_fp=$("$qdrun" --version | sed -n 's/^fingerprint //p')
[ -n "$core_fp" ] || fail "qdrun --version prints no fingerprint"
err=$(env -u QD_PLUGIN_PATH "$qdrun" "$work/exp.toml" -o "$work/runs-debug-stl" --plugin-path "$work/example-debug-stl" 2>&1) && fail "the debug-STL plugin ran"
grep -qF "qd_half_step.so: build fingerprint '$core_fp;glibcxx-debug;glibcxx-assertions' does not match the core's '$core_fp' (plugin only: glibcxx-debug, glibcxx-assertions; core only: -)" <<< "$err" \
  || fail "debug-STL plugin: $err"
echo "install ok"
