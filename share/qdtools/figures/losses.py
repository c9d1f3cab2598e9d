"""losses-<env>-<alg>: the autoencoder's train (solid) and test (dashed) loss per epoch from
losses.csv, epochs cumulative over loops, one colour per loop (the colour bar)."""
import math

import matplotlib
import numpy as np
from matplotlib.lines import Line2D

from ..runs import read_csv
from .common import legend_below, log_ticks, run_title, slug


def plot(out, run):
    path = run.file("losses.csv")
    if path is None:
        return
    rows = read_csv(path)
    if not rows:
        return
    fig = out.figure("losses")
    ax = fig.subplots(1, 1)
    loops = sorted({int(r["loop"]) for r in rows})
    cmap = matplotlib.colormaps["viridis"]
    norm = matplotlib.colors.Normalize(loops[0], max(loops[-1], loops[0] + 1))
    step, data, has_test = 0, {"run": str(run.path), "loops": {}}, False
    for loop in loops:
        rs = [r for r in rows if int(r["loop"]) == loop]
        x = np.arange(step, step + len(rs))
        step += len(rs)
        colour = cmap(norm(loop))
        train = [r["train_loss"] for r in rs]
        test = [r["test_loss"] for r in rs]
        ax.plot(x, train, color=colour, linewidth=1)
        if not all(math.isnan(t) for t in test):
            has_test = True
            ax.plot(x, test, color=colour, linewidth=1, linestyle="--")
        data["loops"][loop] = {"epochs": len(rs), "train_loss": train, "test_loss": test}
    ax.set_yscale("log")
    finite = [v for r in rows for v in (r["train_loss"], r["test_loss"]) if v > 0 and math.isfinite(v)]
    log_ticks(ax.yaxis, min(finite, default=1.0), max(finite, default=10.0))
    ax.set_xlabel("epoch (cumulative over loops)")
    ax.set_ylabel("loss (per-sample SSE)")
    ax.set_title(run_title(run, f"autoencoder losses, {len(loops)} loops"), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, pad=0.02)
    bar.set_label("loop")
    handles = [Line2D([], [], color="0.3", linewidth=1)]
    labels = ["train loss (solid)"]
    if has_test:
        handles.append(Line2D([], [], color="0.3", linewidth=1, linestyle="--"))
        labels.append("test loss (dashed)")
    legend_below(fig, handles, labels, ncol=2, fontsize=8)
    data["epoch_cap"] = run.epoch_cap
    fig.subplots_adjust(left=0.11, right=0.97, top=0.9, bottom=0.18)
    out.save(fig, f"losses-{slug(run.env)}-{slug(run.algorithm)}", "losses", data, [run],
             environment=run.env, algorithm=run.algorithm)
