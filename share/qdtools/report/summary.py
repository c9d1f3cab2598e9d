"""Per-run summaries: what the report's tables say about one run, read from its directory alone
(config.toml, provenance.toml, metrics.csv, status), so a study in results/ gives the same tables
as the full runs did.

A summary is a dict. summarise() fills the core fields below, then calls every function of FIELDS,
each adding its own keys: a new per-run quantity (say, the autoencoder's epochs per loop from
training.csv) is one function appended to FIELDS and one column in sections.py.

A quantity that needs files a study in results/ does not keep (the elites' parameters, per-epoch
logs) goes into KEPT instead: qdresults computes it from the full run when it copies the run and
stores it in the copy's summary.toml, from which summarise() reads it back."""
import math

import numpy as np

from .. import tables
from ..runs import locate, open_text, read_csv, read_toml

SUMMARY = "summary.toml"  # in a study's run directory: the KEPT quantities of the full run


def each_session(run, describe):
    """`describe(provenance)` of each session that made the run, the distinct ones in order, joined
    by "then" (one value for a run made in one go or resumed by the same build on the same CPU)."""
    return " then ".join(dict.fromkeys(describe(p) for p in run.sessions)) or describe({})


def core_fields(run):
    last = run.metrics[-1] if run.metrics else {}
    wall, train = last.get("wall_seconds", math.nan), last.get("train_seconds", math.nan)
    prov = run.provenance
    return {
        "run": run, "dir": run.path, "seed": run.seed, "loops": run.loops, "algorithm": run.algorithm,
        "evaluations": int(last.get("evaluations", 0) or 0), "elites": int(last.get("elites", 0) or 0),
        "cells": prov.get("cells", run.cells or 0),
        "wall": wall if isinstance(wall, float) else math.nan,
        "train": train if isinstance(train, float) else math.nan,
        "workers": prov.get("workers", "?"), "status": run.status or "?",
        "autoencoder": run.representation == "autoencoder", "epoch_cap": run.epoch_cap,
        "index_space": run.index_space, "index_space_label": run.index_space_label,
        "git": each_session(run, lambda p: str(p.get("git_revision", "?"))),
        # Floating-point results depend on the instruction set the run's qdrun was built for.
        "built_for": each_session(run, lambda p: f"{p.get('cpu', '?')}, {p.get('instruction_set', '?')}"),
    }


def mixing_last_loop(run):
    """The share of parameter-space offspring averaged over the run's last loop (per-batch values
    are noisy)."""
    if not run.metrics:
        return {"mixing": math.nan}
    loop = run.metrics[-1]["loop"]
    values = [m.get("mixing_ratio", math.nan) for m in run.metrics if m["loop"] == loop]
    values = [v for v in values if isinstance(v, float) and not math.isnan(v)]
    return {"mixing": sum(values) / len(values) if values else math.nan}


def loop_rates(run):
    """Wall seconds per evaluation (training out) of each loop the run completed, and the metrics
    row that ends each loop."""
    ends = {}
    for r in run.metrics:
        ends[int(r["loop"])] = r

    def work(r):
        train = r.get("train_seconds", math.nan)
        return r["wall_seconds"] - (0.0 if isinstance(train, float) and math.isnan(train) else train)

    rates = {}
    if 0 in ends and ends[0]["evaluations"] > 0:
        rates[0] = work(ends[0]) / ends[0]["evaluations"]
    for L in sorted(ends):
        if L >= 1 and L - 1 in ends and ends[L]["evaluations"] > ends[L - 1]["evaluations"]:
            rates[L] = (work(ends[L]) - work(ends[L - 1])) / (ends[L]["evaluations"] - ends[L - 1]["evaluations"])
    return {"loop_rates": rates, "loop_ends": ends}


def qd_metrics(run):
    """The QD metrics of the run's last metrics row (NaN for a task without fitness) and whether the
    task has a fitness."""
    last = run.metrics[-1] if run.metrics else {}
    values = {k: last.get(k, math.nan) for k in ("qd_score", "max_fitness", "mean_fitness")}
    values = {k: v if isinstance(v, float) else math.nan for k, v in values.items()}
    return dict(values, has_fitness=run.has_fitness())


def training_epochs(run):
    """The representation's epochs per loop (training.csv), [] when it trains nothing."""
    path = run.file("training.csv")
    if path is None:
        return {"epochs_per_loop": []}
    rows = read_csv(path)
    return {"epochs_per_loop": [int(r["epochs"]) for r in rows
                                if isinstance(r.get("epochs"), (int, float)) and not math.isnan(r["epochs"])]}


def elite_parameter_norms(run):
    """The median and maximum Euclidean norm of the final elites' parameter vectors (archive.csv's
    solution_* columns), read a row at a time: the archive can be a hundred megabytes."""
    path = run.file("archive.csv")
    if path is None:
        return {}
    norms = []
    with open_text(path) as f:
        header = f.readline().rstrip("\n").split(",")
        first = next((k for k, name in enumerate(header) if name.startswith("solution_")), None)
        if first is None:
            return {}
        for line in f:
            values = np.array(line.rstrip("\n").split(",")[first:], dtype=float)
            norms.append(float(np.sqrt(values @ values)))
    if not norms:
        return {}
    return {"parameter_norm_median": float(np.median(norms)), "parameter_norm_max": max(norms)}


FIELDS = [mixing_last_loop, loop_rates, training_epochs, qd_metrics]
# Functions of a full run returning {name: number or text}, stored for studies (summary.toml).
KEPT = [elite_parameter_norms]


def kept(run):
    """The KEPT quantities of a run: from its summary.toml when it has one (a study's copy), else
    computed from its files."""
    if locate(run.path / SUMMARY):
        return read_toml(run.path / SUMMARY)
    values = {}
    for field in KEPT:
        values.update(field(run))
    return values


def summarise(run):
    s = core_fields(run)
    for field in FIELDS:
        s.update(field(run))
    s.update(kept(run))
    return s


def epochs_text(summaries):
    """Autoencoder epochs per loop of these runs: '-' without an autoencoder, 'N (paper)', or the cap."""
    paper = tables.algorithms().paper_epochs
    if not any(s["autoencoder"] for s in summaries):
        return "-"
    caps = sorted({s["epoch_cap"] for s in summaries if s["epoch_cap"] is not None})
    if not caps:
        return f"{paper} (paper)"
    return "**capped at " + " / ".join(map(str, caps)) + "**" + (" in some runs" if any(
        s["autoencoder"] and s["epoch_cap"] is None for s in summaries) else "")
