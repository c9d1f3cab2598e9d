#!/usr/bin/env bash
# configure_subsets.sh SRC WORK [cmake args...]: configures SRC once per plugin/environment
# directory alone (-DQD_ONLY_DIRS=<dir>), checking that its plugin target exists, and once with
# -DBUILD_TESTING=OFF, checking that no test is registered. Nothing is built.
set -euo pipefail
src=$1 work=$2
shift 2
rm -rf "$work"
mkdir -p "$work"
configure() {  # configure NAME ARGS...
  local name=$1
  shift
  if ! cmake -S "$src" -B "$work/$name" "$@" > "$work/$name.log" 2>&1; then
    echo "FAIL: $name does not configure (cmake $*):"
    cat "$work/$name.log"
    return 1
  fi
}
status=0
for d in "$src"/plugins/*/ "$src"/environments/*/; do
  [ -f "$d/CMakeLists.txt" ] || continue
  dir=$(basename "$d")
  configure "only-$dir" "$@" -DQD_ONLY_DIRS="$dir" -DQD_BUILD_BENCHMARKS=OFF || { status=1; continue; }
  # The directory's own plugin target (named like the directory) is there, unless the directory
  # skips itself (bipedal and striker without Box2D, as in a full build).
  if ! grep -q "Box2D not found" "$work/only-$dir.log" &&
     ! grep -q "/$dir.dir\$" "$work/only-$dir/CMakeFiles/TargetDirectories.txt"; then
    echo "FAIL: QD_ONLY_DIRS=$dir configures but defines no plugin target $dir"
    status=1
    continue
  fi
  echo "ok: QD_ONLY_DIRS=$dir"
done
configure no-tests "$@" -DBUILD_TESTING=OFF -DQD_BUILD_BENCHMARKS=OFF || exit 1
if [ -n "$(cd "$work/no-tests" && ctest -N | grep 'Test *#')" ]; then
  echo "FAIL: BUILD_TESTING=OFF still registers tests:"
  (cd "$work/no-tests" && ctest -N | head)
  status=1
elif grep -q "_tests.dir$" "$work/no-tests/CMakeFiles/TargetDirectories.txt"; then
  echo "FAIL: BUILD_TESTING=OFF still defines test programs"
  status=1
else
  echo "ok: BUILD_TESTING=OFF registers and builds no tests"
fi
[ $status -eq 0 ] && rm -rf "$work"
exit $status
