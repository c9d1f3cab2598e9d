#!/usr/bin/env bash
# Installs qd into a fresh prefix, builds an out-of-tree plugin against it with find_package(qd)
# and qd_add_plugin(), runs the plugin's own test (the installed conformance checks), checks how
# both were compiled, and runs the plugin through the installed qdrun.
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
# No build type: the example's CMakeLists.txt is the README's four lines, which set none.
cmake -S "$src/example" -B "$work/example-build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
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
  for flag in $arch; do grep -q -- " $flag " <<< "$cmd" || fail "$file was compiled without the core's $flag: $cmd"; done
done
cmake -S "$src/example" -B "$work/example-debug" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DCMAKE_BUILD_TYPE=Debug "${consumer_flags[@]}" \
      > "$work.configure-debug.log" 2>&1 || { cat "$work.configure-debug.log"; exit 1; }
cmd=$(compile_command "$work/example-debug" half_step.cpp)
grep -qE -- ' -O[1-3s]? ' <<< "$cmd" && fail "a Debug build of the plugin was optimised: $cmd"
grep -q -- ' -g ' <<< "$cmd" || fail "a Debug build of the plugin lost -g: $cmd"
# The installed qdrun finds the installed plugins next to itself and the new one on QD_PLUGIN_PATH.
sed 's/^type = "iso"/type = "half-step"/; /^sigma/d' "$src/../../experiments/smoke/iso.toml" > "$work/exp.toml"
listing=$(QD_PLUGIN_PATH="$work/example-build" "$work/prefix/bin/qdrun" --list)
grep -q "half-step" <<< "$listing"
grep -q "poms" <<< "$listing"  # the installed plugins are found next to the installed qdrun
QD_PLUGIN_PATH="$work/example-build" "$work/prefix/bin/qdrun" "$work/exp.toml" -o "$work/runs" -q
grep -qx complete "$work/runs/smoke-iso/seed-7/status"
grep -q "plugin = \"half_step\"" "$work/runs/smoke-iso/seed-7/provenance.toml"
echo "install ok"
