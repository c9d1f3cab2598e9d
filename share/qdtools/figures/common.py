"""What every figure shares: file names, the epoch-cap line, legends outside the data, log ticks."""
import math

import matplotlib.ticker as ticker

from .. import tables


def slug(text):
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in text).lower()


def stem(kind, run_or_env, algorithm=None):
    """File stem of a figure: coverage-<env>, or <kind>-<env>-<algorithm>."""
    if algorithm is None:
        return f"{kind}-{slug(run_or_env)}"
    return f"{kind}-{slug(run_or_env)}-{slug(algorithm)}"


def cap_text(runs):
    """'autoencoder capped at N epochs per loop (paper: 20000)', or '' when no autoencoder run of
    `runs` is capped."""
    ae = [r for r in runs if r.representation == "autoencoder"]
    caps = sorted({r.epoch_cap for r in ae if r.epoch_cap is not None})
    if not caps:
        return ""
    text = "autoencoder capped at " + " / ".join(str(c) for c in caps) + " epochs per loop"
    if any(r.epoch_cap is None for r in ae):
        text += " in some runs"
    return text + f" (paper: {tables.algorithms().paper_epochs})"


def with_cap(title, runs):
    cap = cap_text(runs)
    return f"{title}\n{cap}" if cap else title


def run_title(run, what):
    return with_cap(f"{run.env} {run.algorithm} seed {run.seed}: {what}", [run])


def legend_below(fig, handles, labels, ncol=2, fontsize=7, y=0.005):
    """A figure legend under the axes, where it cannot hide data; returns it."""
    return fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, y), ncol=ncol, fontsize=fontsize,
                      frameon=False)


def log_ticks(axis, lo, hi):
    """Labelled ticks on a log axis spanning [lo, hi]: every power of ten over many decades; 1, 2
    and 5 times each over a few; every integer multiple within about a decade, so a narrow range
    still shows several labelled values."""
    decades = math.log10(hi / lo) if lo > 0 and hi > lo else 0.0
    axis.set_minor_locator(ticker.LogLocator(base=10, subs=tuple(float(k) for k in range(1, 10))))
    axis.set_minor_formatter(ticker.NullFormatter())
    if decades < 0.5:  # less than a factor of 3: evenly spaced round values
        axis.set_major_locator(ticker.MaxNLocator(nbins=5))
        axis.set_major_formatter(ticker.ScalarFormatter())
        return
    subs = (1.0,) if decades > 4 else (1.0, 2.0, 5.0) if decades > 1.5 else tuple(float(k) for k in range(1, 10))
    axis.set_major_locator(ticker.LogLocator(base=10, subs=subs))
    axis.set_major_formatter(ticker.LogFormatterSciNotation(labelOnlyBase=False, minor_thresholds=(100, 100)))
