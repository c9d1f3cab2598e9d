#!/usr/bin/env bash
# expect_error.sh CODE REGEX OUTDIR -- COMMAND...: COMMAND exits with CODE, prints one line matching
# REGEX on stderr, and leaves no run directory that looks complete under OUTDIR.
set -uo pipefail
code=$1 regex=$2 out=$3; shift 4
err=$("$@" 2>&1 >/dev/null); got=$?
if [ "$got" -ne "$code" ]; then echo "exit code $got, expected $code; stderr: $err"; exit 1; fi
if ! grep -Eq -- "$regex" <<< "$err"; then echo "stderr does not match /$regex/: $err"; exit 1; fi
if [ "$(wc -l <<< "$err")" -ne 1 ]; then echo "expected a one-line error, got: $err"; exit 1; fi
if [ -d "$out" ] && find "$out" -name status -exec grep -l complete {} + | grep -q .; then
  echo "a run directory under $out looks complete"; exit 1
fi
echo "ok: $err"
