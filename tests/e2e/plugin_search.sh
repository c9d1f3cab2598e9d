#!/usr/bin/env bash
# plugin_search.sh QDRUN SMOKE_DIR TEST_PLUGIN_ROOT OUT: how qdrun treats the libraries it finds.
#  * A user library that provides "iso" shadows only that name: the built-in library's "none" and
#    "uniform" still run, and one warning names both libraries.
#  * Junk on the plugin path does not lengthen an unknown-component error; a rejected library that
#    offers the name follows it on its own line, with its reason.
source "$(dirname "$0")/lib.sh"
qdrun=$1 smoke=$2 plugins=$3 out=$4
rm -rf "$out"; mkdir -p "$out"
fail() { echo "FAIL: $*"; exit 1; }

"$qdrun" "$smoke/uniform.toml" -o "$out/runs" --plugin-path "$plugins/shadow" 2> "$out/shadow.err" > /dev/null \
  || fail "the run with a shadowing library failed: $(cat "$out/shadow.err")"
grep -qx complete "$out/runs/smoke-uniform/seed-7/status"
warning=$(grep "^qdrun: warning:" "$out/shadow.err") || fail "no warning: $(cat "$out/shadow.err")"
[ "$(wc -l <<< "$warning")" -eq 1 ] || fail "more than one warning: $warning"
grep -qE "qd_basic.so: 'iso' left out, already provided by .*/shadow/qd_shadow.so \(first in the plugin search path wins" <<< "$warning" \
  || fail "warning: $warning"

junk=(--plugin-path "$plugins/garbage" --plugin-path "$plugins/empty" --plugin-path "$plugins/no_entry"
      --plugin-path "$plugins/debug_stl")
err=$("$qdrun" "$smoke/iso.toml" -o "$out/runs-unknown" --set mutator.type=no-such "${junk[@]}" 2>&1) && fail "ran"
[ "$(wc -l <<< "$err")" -eq 1 ] || fail "the unknown-component error has several lines: $err"
grep -q "unknown mutator 'no-such'.* (4 other rejected libraries could not have provided it; qdrun --list shows why)$" <<< "$err" \
  || fail "unknown-component error: $err"
err=$("$qdrun" "$smoke/iso.toml" -o "$out/runs-candidate" --set mutator.type=debug-stl-nothing "${junk[@]}" 2>&1) && fail "ran"
[ "$(wc -l <<< "$err")" -eq 2 ] || fail "expected the error and one rejected library: $err"
grep -q "^  rejected $plugins/debug_stl/qd_debug_stl.so: build fingerprint '.*;glibcxx-debug;glibcxx-assertions' does not match the core's" <<< "$err" \
  || fail "candidate line: $err"
# qdrun --list names each junk file with its reason.
listing=$("$qdrun" --list "${junk[@]}")
grep -qF "$plugins/garbage/qd_garbage.so: is not a shared library (no ELF header" <<< "$listing" || fail "--list: $listing"
grep -qF "$plugins/empty/qd_empty.so: is an empty file" <<< "$listing" || fail "--list: $listing"
echo "plugin search ok"
