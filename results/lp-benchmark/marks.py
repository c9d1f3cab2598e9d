#!/usr/bin/python3
"""The tables of REPORT.md's preface (study.toml), from this study's runs alone: QD score and
coverage at equal evaluations, as mean ± standard deviation over seeds (the form pyribs publishes)
and median, beside pyribs's published values; and the runs on the CMA-ME paper's 500 x 500 grid
(paper-grid/). Run from the repository root:

  results/lp-benchmark/marks.py [STUDY_DIR]

A mark is read at the first metrics row with at least that many evaluations: every loop's end is
kept in the study's thinned metrics.csv.gz (share/qdresults --rows), and the marks are loop ends."""
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "share"))
sys.dont_write_bytecode = True
from qdtools.runs import find_runs, group  # noqa: E402

# 540 + 20 x 54 000 (PoMS's budget here), 540 + 47 x 54 000 (the first loop end past the CMA-ME
# paper's 2.5 million), 540 + 100 x 54 000 (pyribs's 10 000 iterations of 540).
MARKS = (1_080_540, 2_538_540, 5_400_540)
# docs.pyribs.org, "Sphere Function with Various Algorithms" (pyribs/docs/examples/sphere.md): mean
# ± standard deviation over 20 trials of 10 000 iterations of 540, n = 100, 100 x 100 grid or 10 000
# CVT cells: QD score, coverage in %.
PYRIBS = {"MAPE-Iso": ("map_elites", 416_111.64, 2_681.37, 50.72, 0.40),
          "MAPE-IsoLineDD": ("line_map_elites", 491_013.92, 1_118.74, 60.44, 0.17),
          "MAPE-Iso CVT": ("cvt_map_elites", 416_350.11, 3_942.42, 50.67, 0.49),
          "cma-me": ("cma_me_imp", 456_678.01, 2_882.10, 55.84, 0.41)}
ORDER = ["MAPE-Iso", "MAPE-IsoLineDD", "cma-me", "PoMS", "MAPE-Iso CVT", "PoMS CVT"]


def at(run, evaluations):
    """(QD score, coverage %) at the first row with at least `evaluations`, or None."""
    for m in run.metrics:
        if m["evaluations"] >= evaluations:
            return m["qd_score"], 100 * m["coverage"]
    return None


def stats(values):
    sd = statistics.stdev(values) if len(values) > 1 else 0.0
    return statistics.fmean(values), sd, statistics.median(values)


def number(x, digits=0):
    return f"{x:,.{digits}f}".replace(",", " ")


def table(groups, env, marks, published):
    head = "| algorithm | seeds | evaluations | QD score: mean ± sd (median) | coverage %: mean ± sd (median) |"
    lines = [head + (" pyribs, published: QD score; coverage % |" if published else ""),
             "|---|---|---|---|---|" + ("---|" if published else "")]
    for alg in sorted(groups.get(env, {}), key=lambda a: ORDER.index(a) if a in ORDER else len(ORDER)):
        runs = groups[env][alg]
        for mark in marks:
            values = [at(r, mark) for r in runs]
            if any(v is None for v in values):
                continue
            evals = {next(m["evaluations"] for m in r.metrics if m["evaluations"] >= mark) for r in runs}
            qd, cov = stats([v[0] for v in values]), stats([v[1] for v in values])
            row = (f"| {alg} | {len(runs)} | {'/'.join(number(e) for e in sorted(evals))} | "
                   f"{number(qd[0])} ± {number(qd[1])} ({number(qd[2])}) | "
                   f"{cov[0]:.2f} ± {cov[1]:.2f} ({cov[2]:.2f}) |")
            if published:
                p = PYRIBS.get(alg) if mark == MARKS[-1] else None
                row += f" `{p[0]}`: {number(p[1])} ± {number(p[2])}; {p[3]:.2f} ± {p[4]:.2f} |" if p else " |"
            lines.append(row)
    return lines


def main(study):
    study = Path(study)
    groups = group([r for r in find_runs([study / "runs"]) if r.complete])
    for env in ("lp-sphere", "lp-rastrigin"):
        print(f"\n{env}, 100 x 100 grid (or 10 000 CVT cells):\n")
        print("\n".join(table(groups, env, MARKS, env == "lp-sphere")))
    paper = study / "paper-grid"
    if paper.is_dir():
        groups = group([r for r in find_runs([paper]) if r.complete])
        for env in groups:
            print(f"\n{env}, the CMA-ME paper's 500 x 500 grid (batch 555; paper-grid/):\n")
            print("\n".join(table(groups, env, (1_000_000, 2_498_055), False)))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent)
