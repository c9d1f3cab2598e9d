"""qd-<env>: the QD metrics of metrics.csv against evaluations, for tasks with a fitness: the QD score
(the sum over the elites of fitness minus the task's lower bound), the best and the mean fitness of
the elites; per algorithm the median and 25-75 % band over seeds, as the coverage figure draws them.
Runs whose task has no fitness (the PoMS paper's) have none: the figure is not drawn for them."""
import math

import numpy as np
from matplotlib.patches import Patch

from .. import stats, tables
from .common import legend_below, stem, with_cap

# metrics.csv column -> axis label
METRICS = {"qd_score": "QD score", "max_fitness": "max fitness", "mean_fitness": "mean fitness"}
MAX_MARKERS = 60


def bound_text(runs):
    """Where the QD score's zero comes from: the experiment files' fitness_lower_bound, else the
    environment's."""
    bounds = sorted({r.config["experiment"].get("fitness_lower_bound") for r in runs}, key=str)
    finite = [b for b in bounds if isinstance(b, (int, float)) and not math.isnan(b)]
    if len(finite) == len(bounds) == 1:
        return f"fitness_lower_bound = {finite[0]:g}"
    if not finite:
        return "the environment's fitness lower bound"
    return "fitness_lower_bound = " + " / ".join(str(b) for b in bounds)


def plot(out, env, groups):
    algs = tables.algorithms()
    fitted = {a: rs for a, rs in groups.items() if any(r.has_fitness() for r in rs)}
    if not fitted:
        print(f"qdplot: no QD figure for {env}: its task has no fitness (metrics.csv's qd_score is empty)")
        return
    styles = algs.styles(fitted)
    fig = out.figure("qd")
    axes = fig.subplots(len(METRICS), 1, sharex=True)
    data = {"environment": env, "metrics": list(METRICS), "algorithms": {}}
    handles, labels, everyone = [], [], []
    for alg in sorted(fitted, key=algs.rank):
        runs = sorted((r for r in fitted[alg] if r.has_fitness()), key=lambda r: r.seed)
        everyone += runs
        colour, marker, linestyle = styles[alg]
        ends = stats.loop_ends(max(runs, key=lambda r: len(r.metrics)))
        entry = {"seeds": [r.seed for r in runs], "runs": [str(r.path) for r in runs], "loop_end_evaluations": ends}
        final = {}
        for ax, key in zip(axes, METRICS):
            x, ys = stats.series(runs, lambda r, m, key=key: m.get(key, math.nan), before=math.nan)
            med, q25, q75 = (stats.nearest_percentile(ys, q) for q in (50, 25, 75))
            marks = [int(np.searchsorted(x, e)) for e in ends if e <= x[-1]]
            if len(marks) > MAX_MARKERS:
                marks = marks[::math.ceil(len(marks) / MAX_MARKERS)]
            ax.fill_between(x, q25, q75, color=colour, alpha=0.2, linewidth=0)
            (line,) = ax.plot(x, med, color=colour, marker=marker, markevery=marks, markersize=4, linewidth=1.3,
                              linestyle=linestyle)
            final[key] = stats.nearest([r.last(key) for r in runs], 50)
            entry[key] = {"evaluations": x.tolist(), "median": med.tolist(), "q25": q25.tolist(), "q75": q75.tolist(),
                          "final_median": final[key]}
        handles.append(line)
        labels.append(f"{alg} ({len(runs)} seed{'s' if len(runs) > 1 else ''}): QD score {final['qd_score']:.6g}, "
                      f"max fitness {final['max_fitness']:.4g}, mean {final['mean_fitness']:.4g}")
        data["algorithms"][alg] = entry
    handles.append(Patch(color="0.5", alpha=0.3, linewidth=0))
    labels.append("25-75 % over seeds")
    data["bound"] = bound_text(everyone)
    for ax, (key, name) in zip(axes, METRICS.items()):
        ax.set_ylabel(name, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"QD score\n(sum of fitness - bound)", fontsize=9)
    axes[0].set_title(with_cap(f"{env}: QD metrics, median over seeds, a marker per loop; final medians in the "
                               f"legend\nQD score's zero: {data['bound']}", everyone), fontsize=10)
    axes[-1].set_xlabel("evaluations")
    axes[-1].ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    legend_below(fig, handles, labels, ncol=1)
    fig.subplots_adjust(left=0.12, right=0.97, top=0.9, bottom=0.07 + 0.022 * len(labels), hspace=0.1)
    out.save(fig, stem("qd", env), "qd", data, everyone, environment=env)
