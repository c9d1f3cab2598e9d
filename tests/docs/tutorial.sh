#!/usr/bin/env bash
# docs/tutorial.md as a newcomer runs it: every ```sh block, as written, in order, in a fresh copy of
# the tracked files (a clean clone) with HOME in a scratch directory, then what the tutorial says
# they make. One block is not run as written: the one marked `<!-- tutorial: setup -->`
# (scripts/quickstart.sh, which installs Debian packages and builds the whole tree in build/, then
# `cmake --install build --prefix ~/qd`): the test installs the suite's own build into ~/qd instead,
# the same files that command installs (e2e.quickstart runs the quick start's run and figures).
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work"
mkdir -p "$work/home" "$work/clone"
export HOME=$work/home
if git -C "$src" rev-parse --is-inside-work-tree > /dev/null 2>&1; then
  (cd "$src" && git ls-files -z | xargs -0 cp --parents -t "$work/clone")
else
  (cd "$src" && find . -path './build*' -prune -o -path './.git' -prune -o -type f -print0 | xargs -0 cp --parents -t "$work/clone")
fi
cmake --install "$build" --prefix "$HOME/qd" > "$work/install.log" 2>&1 || { cat "$work/install.log"; exit 1; }

# The blocks: ```sh ... ``` in the order of the file; the one after the setup marker is left out.
/usr/bin/python3 - "$src/docs/tutorial.md" "$work/blocks" <<'PY'
import re, sys
from pathlib import Path
text = Path(sys.argv[1]).read_text()
out = Path(sys.argv[2])
out.mkdir()
blocks = list(re.finditer(r"(<!-- tutorial: setup -->\n)?```sh\n(.*?)```\n", text, re.DOTALL))
assert sum(1 for b in blocks if b.group(1)) == 1, "exactly one setup block"
n = 0
for b in blocks:
    if not b.group(1):
        n += 1
        (out / f"{n:02d}.sh").write_text(b.group(2))
print(f"tutorial: {n} blocks to run")
PY
cd "$work/clone"
for block in "$work"/blocks/*.sh; do
  echo "== $(basename "$block")"
  bash -euo pipefail "$block" > "$block.log" 2>&1 || { echo "tutorial block failed:"; cat "$block"; cat "$block.log"; exit 1; }
done

# What the tutorial says the commands make.
fail() { echo "FAIL: $*"; exit 1; }
grep -q "^sweep: estimated [0-9.]* core-hours" "$work/blocks/02.sh.log" || fail "no estimate: $(cat "$work/blocks/02.sh.log")"
for run in striker-iso/seed-1 striker-iso/seed-2 striker-iso-line-dd/seed-1 striker-iso-line-dd/seed-2 \
           striker-half-step/seed-1 striker-half-step/seed-2; do
  grep -qx complete "runs/$run/status" || fail "runs/$run is not complete"
  [ "$(tail -n 1 "runs/$run/metrics.csv" | cut -d, -f3)" = 22000 ] || fail "runs/$run did not run 22000 evaluations"
done
for f in coverage-striker map-striker-mape-iso map-striker-mape-isolinedd traces-striker-mape-iso; do
  [ -s "figures/$f.png" ] || fail "figures/$f.png was not drawn: $(ls figures)"
done
grep -q "100% tests passed" "$work/blocks/04.sh.log" || fail "the plugin's test: $(cat "$work/blocks/04.sh.log")"
grep -q 'param_float("step", "0.25"' my-mutator/half_step.hpp
grep -q '^type = .half-step.$' runs/striker-half-step/seed-1/config.toml
grep -q '^step = 0.25$' runs/striker-half-step/seed-1/config.toml || fail "the run did not take the new default"
/usr/bin/python3 - "$HOME/qd/share/qd" <<'PY'
import json, sys
sys.path.insert(0, sys.argv[1])
from qdtools.runs import Run
coverage = [e for e in json.load(open("figures/qdplot.json"))["files"] if e["file"] == "coverage-striker.png"]
names = sorted({Run(r).algorithm for r in coverage[0]["runs"]})
assert names == ["MAPE-Iso", "MAPE-IsoLineDD", "striker-half-step"], names
print("tutorial ok")
PY
