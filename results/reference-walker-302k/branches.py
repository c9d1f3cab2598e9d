#!/usr/bin/python3
"""Per-loop insertions by branch for a PoMS run with output.snapshot_every = 1.

An elite whose stored reconstruction error is exactly 0 came from the latent branch (PoMS stores
0 for offspring decoded from the manifold); any other came from the parameter-space branch or
loop 0. For each loop k >= 1, the cells that are new or whose elite changed since loop k-1 are
counted by branch, with the median parameter norm of what entered; the archive's share of
zero-error elites and of elites above the archive's mean error (the parents that the mixing rule
sends to the parameter-space branch) is given at the end of each loop.
usage: analyze.py RUN_DIR [STUDY_RUN_DIR]
"""
import csv, sys
import numpy as np
from pathlib import Path

run = Path(sys.argv[1])

def load(p):
    with open(p) as f:
        r = csv.reader(f)
        head = next(r)
        rows = [list(map(float, x)) for x in r]
    a = np.array(rows)
    ix = head.index("index"); ie = head.index("recn_error")
    sol = [i for i, h in enumerate(head) if h.startswith("solution_")]
    return {int(x[ix]): (x[ie], x[sol]) for x in a}

# Offspring per loop and branch: evaluations in the loop times its mean mixing ratio (the share
# of parents sent to the parameter-space branch).
with open(run / "metrics.csv") as f:
    mrows = list(csv.DictReader(f))
per_loop = {}
for m in mrows:
    per_loop.setdefault(int(m["loop"]), []).append(m)
def offspring(k):
    rows = per_loop.get(k, [])
    if not rows or k == 0:
        return None
    evals = int(rows[-1]["evaluations"]) - int(per_loop[k - 1][-1]["evaluations"])
    mix = float(np.mean([float(r["mixing_ratio"]) for r in rows]))
    return evals * (1 - mix), evals * mix, mix

snaps = sorted((run / "archive").glob("loop-*.csv"))
prev = None
print("| loop | cells | mixing ratio (mean) | entered: latent | entered: parameter | entered per 100 offspring: latent / parameter | median norm entered, latent | median norm entered, parameter | share of elites with error 0 | share above mean error | median norm, archive |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for p in snaps:
    k = int(p.stem.split("-")[1])
    cur = load(p)
    errs = np.array([e for e, _ in cur.values()])
    norms = np.array([np.linalg.norm(s) for _, s in cur.values()])
    if prev is None:
        lat = par = []
    else:
        entered = [c for c, (e, s) in cur.items() if c not in prev or not np.array_equal(prev[c][1], s)]
        lat = [np.linalg.norm(cur[c][1]) for c in entered if cur[c][0] == 0]
        par = [np.linalg.norm(cur[c][1]) for c in entered if cur[c][0] != 0]
    med = lambda v: f"{np.median(v):.1f}" if len(v) else "-"
    o = offspring(k)
    rate = f"{100 * len(lat) / o[0]:.1f} / {100 * len(par) / o[1]:.1f}" if o and o[1] > 0 else "-"
    mixs = f"{o[2]:.3f}" if o else "-"
    print(f"| {k} | {len(cur)} | {mixs} | {len(lat)} | {len(par)} | {rate} | {med(lat)} | {med(par)} | "
          f"{np.mean(errs == 0):.3f} | {np.mean(errs > errs.mean()):.3f} | {np.median(norms):.1f} |")
    prev = cur

if len(sys.argv) > 2:
    # The diagnostic run is the study's run: same rows of metrics.csv but the timing columns.
    def rows(p):
        with open(p) as f:
            r = list(csv.reader(f))
        h = r[0]; drop = {h.index("wall_seconds"), h.index("train_seconds")}
        return [[v for i, v in enumerate(x) if i not in drop] for x in r[1:]]
    a, b = rows(run / "metrics.csv"), rows(Path(sys.argv[2]) / "metrics.csv")
    same = a == b[:len(a)]
    print(f"\nmetrics.csv: {len(a)} rows, {'identical to' if same else 'DIFFERENT from'} the study run's first {len(a)} (timing columns aside)")
