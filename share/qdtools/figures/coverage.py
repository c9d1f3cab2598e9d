"""coverage-<env>: coverage against evaluations, median and 25-75 % band over seeds per algorithm,
a marker at every loop boundary, and below it the mixing ratio of the algorithms the table marks
(the share of offspring made in parameter space, as the paper's lower panel)."""
import math

import numpy as np
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter

from .. import stats, tables
from .common import legend_below, stem, with_cap

RATIO_WINDOW = 10000  # evaluations of the mixing ratio's moving average, as the paper's figures
MAX_MARKERS = 60      # PS runs: every row is a loop end; keep the figure readable


def plot(out, env, groups):
    algs = tables.algorithms()
    fig = out.figure("coverage")
    # Other operators log a constant or another quantity as their mixing ratio (the mutators' READMEs).
    has_ratio = any(not math.isnan(m.get("mixing_ratio", math.nan)) for alg, runs in groups.items()
                    if algs.plots_mixing_ratio(alg) for r in runs for m in r.metrics)
    if has_ratio:
        ax, axr = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    else:
        ax, axr = fig.subplots(1, 1), None
    data = {"environment": env, "algorithms": {}}
    handles, labels, ratio_names, everyone = [], [], [], []
    cells = index_space = index_label = None
    styles = algs.styles(groups)
    for alg in sorted(groups, key=algs.rank):
        runs = sorted(groups[alg], key=lambda r: r.seed)
        everyone += runs
        cells, index_space, index_label = runs[0].cells, runs[0].index_space, runs[0].index_space_label
        colour, marker, linestyle = styles[alg]
        x, ys = stats.coverage_series(runs)
        med, q25, q75 = (stats.nearest_percentile(ys, q) for q in (50, 25, 75))
        # Runs of unequal length (a study still running): the curve is solid where every seed has
        # run and dotted beyond, where the median is over fewer seeds; the legend gives the median
        # where all seeds have run.
        reaching = np.sum(~np.isnan(ys), axis=0)
        full = int(np.flatnonzero(reaching == len(runs))[-1])
        if full == len(x) - 1:
            final = int(stats.nearest([r.final_elites() for r in runs], 50))
            seeds = f"{len(runs)} seed{'s' if len(runs) > 1 else ''}"
        else:
            final = int(round(med[full] * runs[0].cells / 100))
            seeds = f"{len(runs)} seeds; {int(reaching[-1])} past {evaluations_tick(x[full])}, dotted"
        label = f"{alg} ({seeds}): {final} cells, {100 * final / cells:.2f} %"
        if index_space:
            label += f" ({100 * final / index_space:.2f} % of {index_space})"
        caps = sorted({r.epoch_cap for r in runs if r.epoch_cap is not None})
        if caps:
            label += ", autoencoder capped at " + "/".join(map(str, caps)) + " epochs"
        ax.fill_between(x[:full + 1], q25[:full + 1], q75[:full + 1], color=colour, alpha=0.2, linewidth=0)
        ends = stats.loop_ends(max(runs, key=lambda r: len(r.metrics)))
        marks = [int(np.searchsorted(x, e)) for e in ends if e <= x[full]]
        if len(marks) > MAX_MARKERS:
            marks = marks[::math.ceil(len(marks) / MAX_MARKERS)]
        (line,) = ax.plot(x[:full + 1], med[:full + 1], color=colour, marker=marker, markevery=marks, markersize=4,
                          linewidth=1.3, linestyle=linestyle)
        if full < len(x) - 1:
            ax.plot(x[full:], med[full:], color=colour, linewidth=1.0, linestyle=":")
        handles.append(line)
        labels.append(label)
        entry = {"seeds": [r.seed for r in runs], "runs": [str(r.path) for r in runs], "cells": cells,
                 "index_space": index_space, "final_median_elites": final, "epoch_caps": caps,
                 "evaluations": x.tolist(), "median": med.tolist(), "q25": q25.tolist(), "q75": q75.tolist(),
                 "runs_reaching": reaching.tolist(), "loop_end_evaluations": ends}
        if axr is not None and algs.plots_mixing_ratio(alg):
            ratio = mixing_ratio(runs)
            if ratio is not None:
                ev, mean, std = ratio
                (rline,) = axr.plot(ev, mean, color=colour, linewidth=1.2, linestyle=linestyle)
                axr.fill_between(ev, mean - std, mean + std, color=colour, alpha=0.2, linewidth=0)
                ratio_names.append(alg)
                handles.append(rline)
                labels.append(f"{alg}: mixing ratio (lower panel)")
                entry["mixing_ratio"] = {"evaluations": ev.tolist(), "mean": mean.tolist(), "std": std.tolist()}
        data["algorithms"][alg] = entry
    handles.append(Patch(color="0.5", alpha=0.3, linewidth=0))
    labels.append("25-75 % over seeds" + (" (upper); ± 1 std over seeds (lower)" if ratio_names else ""))
    ax.set_ylabel(f"coverage (% of {cells} cells)")
    ax.set_title(with_cap(f"{env}: coverage, median over seeds, a marker per loop; final median in the legend",
                          everyone), fontsize=10)
    if any(", dotted)" in label for label in labels):
        ax.set_title(with_cap(f"{env}: coverage, median over seeds (dotted: fewer seeds), a marker per loop;\n"
                              "in the legend the median where every seed has run", everyone), fontsize=9)
    ax.grid(alpha=0.3)
    ax.set_ylim(bottom=0)
    if index_space:  # the same curves in % of the reference's index space (the Walker's 50 000)
        ratio_of = cells / index_space
        sec = ax.secondary_yaxis("right", functions=(lambda y: y * ratio_of, lambda y: y / ratio_of))
        sec.set_ylabel(f"% of {index_space} ({index_label})", fontsize=8)
    bottom = ax
    if axr is not None:
        axr.set_ylabel("mixing ratio", fontsize=8)
        axr.set_title(f"mixing ratio ({', '.join(ratio_names)}), as the paper's figures: mean over seeds at each "
                      f"evaluation,\ncentred {RATIO_WINDOW}-evaluation moving average", fontsize=7, loc="left")
        axr.set_ylim(-0.05, 1.05)
        axr.grid(alpha=0.3)
        bottom = axr
    bottom.set_xlabel("evaluations")
    bottom.xaxis.set_major_formatter(FuncFormatter(evaluations_tick))
    ncol = 1 if any(", dotted)" in label for label in labels) else 2  # those labels are too long for two
    rows = math.ceil(len(labels) / ncol)
    legend_below(fig, handles, labels, ncol=ncol)
    fig.subplots_adjust(left=0.1, right=0.9 if index_space else 0.97, top=0.91, bottom=0.1 + 0.028 * rows,
                        hspace=0.25)
    out.save(fig, stem("coverage", env), "coverage", data, everyone, environment=env)


def evaluations_tick(x, _pos=None):
    """An evaluation count as a tick label: 0, 500, 20k, 1.5M."""
    if abs(x) >= 1e6:
        return f"{x / 1e6:g}M"
    return f"{x / 1e3:g}k" if abs(x) >= 1e3 else f"{x:g}"


def mixing_ratio(runs, points=2000):
    """(evaluations, mean, std) of the runs' mixing ratio aggregated as the paper's figures do
    (stats.paper_mixing_ratio: per evaluation, mean over seeds, then a centred RATIO_WINDOW moving
    mean), thinned to about `points` points for drawing; None when no run has one."""
    ratio = stats.paper_mixing_ratio(runs, RATIO_WINDOW)
    if ratio is None:
        return None
    ev, mean, std = ratio
    keep = np.unique(np.concatenate([np.arange(0, ev.size, max(1, ev.size // points)), [ev.size - 1]]))
    return ev[keep], mean[keep], std[keep]
