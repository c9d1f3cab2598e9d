"""The sweep a report runs: its qdrun command, the dry-run estimate kept before its first run
(estimate.txt) and every invocation's wall time and outcome (invocations.csv)."""
import datetime
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

from ..runs import read_csv


def command(qdrun, files, seeds, runs_root, evaluations=None, loops=None, max_epochs=None, sets=(), jobs=None):
    sweep = [qdrun] + [str(f) for f in files] + ["--seeds", seeds, "-o", str(runs_root)]
    if evaluations is not None:
        sweep += ["--evaluations", str(evaluations)]
    if loops is not None:
        sweep += ["--set", f"experiment.loops={loops}"]
    if max_epochs is not None:
        sweep += ["--set-optional", f"representation.max_epochs={max_epochs}"]
    for s in sets:
        sweep += ["--set", s]
    if jobs:
        sweep += ["--jobs", str(jobs)]
    return sweep


def save_estimate(out, sweep, shown):
    """Runs the sweep with --dry-run and keeps its estimate in OUT/estimate.txt (once: the estimate
    made before the first run). Exits on bad input (exit code 2)."""
    print("qdreport: " + shlex.join(sweep + ["--dry-run"]), flush=True)
    dry = subprocess.run(sweep + ["--dry-run"], capture_output=True, text=True)
    sys.stdout.write(dry.stdout)
    sys.stderr.write(dry.stderr)
    if dry.returncode == 2:
        sys.exit("qdreport: the sweep rejected its input (see above)")
    if dry.returncode == 0 and "\nsweep: estimated" in dry.stdout:
        # The estimate without the plan's command lines, which hold this machine's paths.
        estimate = dry.stdout[dry.stdout.index("estimate ("):]
        tmp = out / "estimate.txt.tmp"
        tmp.write_text(f"# {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, before the sweep's "
                       f"first run: {shown(sweep + ['--dry-run'])}\n" + estimate)
        tmp.replace(out / "estimate.txt")
    else:
        print(f"qdreport: no estimate (qdrun --dry-run exited with {dry.returncode}); the sweep runs anyway",
              file=sys.stderr)


def read_estimate(path):
    """The per-run estimates and the sweep's totals of a saved `qdrun --dry-run` (estimate.txt): per
    run its core-hours and the part of them that is episodes (the rest is training, which a run's
    worker count does not divide); an older line without the parts counts as episodes only.
    A study made by several sweeps (one after another, each of different runs) keeps each sweep's
    dry-run in the same file: the totals add up, `sweeps` counts them, and `jobs` is None when they
    ran a different number of runs at a time. A later estimate of the same run replaces the earlier
    one (comment out the sweep line of a dry-run whose runs an earlier one already counted)."""
    per_run, totals = {}, []
    for line in Path(path).read_text().splitlines():
        m = re.match(r"^  (\S+/seed-\d+) +([0-9.]+) core-h:(?: \d+ evaluations ([0-9.]+) h, training [0-9.]+ h)?", line)
        if m:
            core_h = float(m[2])
            per_run[m[1]] = {"core_h": core_h, "episodes_h": float(m[3]) if m[3] else core_h}
        m = re.match(r"^sweep: estimated ([0-9.]+) core-hours .*?(\d+) at a time on (\d+) cores?: about ([0-9.]+) hours",
                     line)
        if m:
            totals.append({"core_h": float(m[1]), "jobs": int(m[2]), "cores": int(m[3]), "wall_h": float(m[4])})
    if not totals:
        return per_run, None
    same = len({(t["jobs"], t["cores"]) for t in totals}) == 1
    return per_run, {"core_h": sum(t["core_h"] for t in totals), "wall_h": sum(t["wall_h"] for t in totals),
                     "jobs": totals[0]["jobs"] if same else None, "cores": totals[0]["cores"] if same else None,
                     "sweeps": len(totals)}


def read_invocations(path):
    """The sweep invocations qdreport logged (invocations.csv): started_utc, wall_seconds,
    exit_code, summary (as text)."""
    return read_csv(path, text=True) if Path(path).exists() else []


def log_invocation(path, started, seconds, outcome, summary):
    """Adds or completes the row of the invocation that started at `started` (rewritten atomically)."""
    rows = [r for r in read_invocations(path) if r["started_utc"] != started]
    rows.append({"started_utc": started, "wall_seconds": seconds, "exit_code": outcome,
                 "summary": summary.replace(",", ";")})
    tmp = Path(path).with_suffix(".tmp")
    tmp.write_text("started_utc,wall_seconds,exit_code,summary\n" +
                   "".join(f"{r['started_utc']},{r['wall_seconds']},{r['exit_code']},{r['summary']}\n" for r in rows))
    tmp.replace(path)


def run(out, sweep):
    """Runs the sweep, its output shown and appended to OUT/sweep.log, the invocation logged even
    when it is stopped. Returns (exit code, wall seconds, the sweep's summary line)."""
    started = f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%dT%H:%M:%SZ}"
    print("qdreport: " + shlex.join(sweep), flush=True)
    t0 = time.monotonic()
    log_invocation(out / "invocations.csv", started, "", "running", "")
    # A session that ends (SIGTERM, SIGHUP) still logs how long this invocation ran.
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda signum, frame: sys.exit(128 + signum))
    p, outcome, rc, summary = None, "interrupted", 0, ""
    try:
        with open(out / "sweep.log", "a") as log:
            # Its own process group: stopping qdreport stops the sweep and every run it started.
            p = subprocess.Popen(sweep, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 start_new_session=True)
            for line in p.stdout:
                sys.stdout.write(line)
                sys.stdout.flush()
                if line.startswith("sweep: ") and " runs: " in line:
                    summary = line.strip()[len("sweep: "):]
                log.write(line)
            rc = p.wait()
            outcome = str(rc)
    finally:
        if p is not None and p.poll() is None:
            # Each run stops on SIGTERM with its last checkpoint intact: the same command resumes it.
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
            for _ in range(600):  # the runs write their status and exit
                try:
                    os.killpg(p.pid, 0)
                except ProcessLookupError:
                    break
                time.sleep(0.1)
        seconds = time.monotonic() - t0
        log_invocation(out / "invocations.csv", started, f"{seconds:.1f}", outcome, summary)
    if rc == 2:
        sys.exit("qdreport: the sweep rejected its input (see above)")
    return rc, seconds, summary

