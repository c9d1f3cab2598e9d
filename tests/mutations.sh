#!/usr/bin/env bash
# Deliberate bugs in the algorithm, each of which must make at least one test fail (tests/README.md
# lists them with the tests that catch them). Not part of the test suite: it edits the source tree
# in place (restoring every file at the end, even on failure), rebuilds BUILD_DIR for each bug and
# runs the tests named for it. Takes a few minutes.
#
#   tests/mutations.sh BUILD_DIR          e.g. tests/mutations.sh build-test
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "$1" && pwd)
cd "$root"
touched=()
restore() { [ ${#touched[@]} -eq 0 ] || git checkout -q -- "${touched[@]}"; touched=(); }
trap restore EXIT

# name | file | perl substitution (must match) | ctest regex of the tests that should catch it
mutations=(
  "always replace|core/src/runtime/map_elites.cpp|s/replace = by_fitness \? r\.fitness > r\.previous : coin\.uniform\(\) < s_\.replace_probability;/replace = by_fitness ? r.fitness > r.previous : true;/|MapElitesLoop|golden"
  "never replace|core/src/runtime/map_elites.cpp|s/replace = by_fitness \? r\.fitness > r\.previous : coin\.uniform\(\) < s_\.replace_probability;/replace = by_fitness ? r.fitness > r.previous : false;/|MapElitesLoop|golden"
  "fitness rule not strict|core/src/runtime/map_elites.cpp|s/replace = by_fitness \? r\.fitness > r\.previous/replace = by_fitness ? r.fitness >= r.previous/|MapElitesLoop|golden"
  "no dataset growth|core/src/runtime/map_elites.cpp|s/dataset_\.add\(archive_\.params\(static_cast<std::size_t>\(archive_\.slot_of\(cell\)\)\), cell, loop\);/(void)cell;/|MapElitesLoop|golden"
  "selection with replacement|core/src/runtime/grid_archive.cpp|s/if \(m >= n\) \{/if (false) {/|MapElitesLoop|golden"
  "threshold = median|plugins/poms/poms.cpp|s/threshold_ = ctx\.archive->mean_recn_error\(\);/{ std::vector<double> e; for (std::size_t k = 0; k < ctx.archive->size(); ++k) e.push_back(ctx.archive->recn_error(k)); std::sort(e.begin(), e.end()); threshold_ = e.empty() ? 0.0 : e[e.size() \/ 2]; }/|PomsTest|golden"
  "Jacobian transposed in the latent step|core/src/interfaces.cpp|s/= v\.row\(i\) \* jac\[static_cast<std::size_t>\(i\)\];/= v.row(i) * jac[static_cast<std::size_t>(i)].transpose();/|PomsTest"
  "mixing ratio over the latent offspring|plugins/poms/poms.cpp|s/static_cast<double>\(high\.size\(\)\) \/ static_cast<double>\(count\)/static_cast<double>(high.size()) \/ static_cast<double>(count - high.size())/|PomsTest|golden"
)
[ -n "$(git status --porcelain -- core plugins)" ] && { echo "core/ or plugins/ has uncommitted changes: commit or stash them first"; exit 2; }
caught=0 missed=0
for m in "${mutations[@]}"; do
  IFS='|' read -r name file subst tests <<< "$m"
  perl -0pi -e "$subst" "$file"
  touched=("$file")
  if git diff --quiet -- "$file"; then
    echo "ERROR: '$name' did not apply to $file"; restore; missed=$((missed + 1)); continue
  fi
  [[ $file == plugins/poms/* ]] && sed -i '1a #include <algorithm>\n#include <vector>' "$file"
  if ! cmake --build "$build" > /tmp/qd-mutation-build.log 2>&1; then
    echo "caught at build time: $name"; caught=$((caught + 1)); restore; continue
  fi
  failed=$(cd "$build" && ctest -R "$tests" --timeout 300 2>&1 | sed -n 's/^[[:space:]]*[0-9]* - \(.*\) (Failed)$/\1/p' | tr '\n' ' ')
  if [ -n "$failed" ]; then
    echo "caught: $name -- failing: $failed"; caught=$((caught + 1))
  else
    echo "MISSED: $name (no test in /$tests/ failed)"; missed=$((missed + 1))
  fi
  restore
done
cmake --build "$build" > /dev/null 2>&1
echo "$caught caught, $missed missed"
[ "$missed" -eq 0 ]
