"""Statistics over seeds as the reference's plots compute them: numpy's 'nearest' percentiles, the
coverage curve as a step function of evaluations, and the mixing ratio aggregated as
the paper's figures aggregate it (paper_mixing_ratio)."""
import math

import numpy as np


def nearest(values, q):
    """The q-th percentile of `values` by numpy's 'nearest' rule (the element at rank
    round(q/100 (n-1)), halves to even); NaN for no values."""
    s = sorted(values)
    return s[int(round(q / 100 * (len(s) - 1)))] if s else math.nan


def nearest_percentile(ys, q):
    """Per column of `ys` (seeds x points), the 'nearest' percentile over the non-NaN values."""
    ys = np.asarray(ys, dtype=float)
    out = np.full(ys.shape[1], np.nan)
    for j in range(ys.shape[1]):
        col = ys[:, j][~np.isnan(ys[:, j])]
        if col.size:
            out[j] = nearest(col.tolist(), q)
    return out


def coverage_series(runs):
    """The evaluation counts of every run's rows (union, sorted) and each run's coverage in percent
    of its cells there: the coverage after the last row at or before x, NaN past the run's end."""
    return series(runs, lambda r, m: 100.0 * m["elites"] / r.cells)


def series(runs, value, before=0.0):
    """The evaluation counts of every run's rows (union, sorted) and each run's `value(run, row)`
    there: the value of the last row at or before x (`before` before the first), NaN past the run's
    end."""
    x = np.array(sorted({m["evaluations"] for r in runs for m in r.metrics}))
    ys = []
    for r in runs:
        ev = np.array([m["evaluations"] for m in r.metrics])
        v = np.array([value(r, m) for m in r.metrics], dtype=float)
        idx = np.searchsorted(ev, x, side="right") - 1
        y = np.where(idx >= 0, v[np.clip(idx, 0, None)], before)
        y[x > ev[-1]] = np.nan
        ys.append(y)
    return x, np.array(ys)


def loop_ends(run):
    """The cumulative evaluations at the end of each loop of a run."""
    ends = {}
    for m in run.metrics:
        ends[int(m["loop"])] = m["evaluations"]
    return sorted(ends.values())


def mean(values):
    values = [v for v in values if not (isinstance(v, float) and math.isnan(v))]
    return sum(values) / len(values) if values else math.nan


def per_evaluation(run, key="mixing_ratio"):
    """A run's `key` at every evaluation, as the paper's plotting code lays it out: each metrics row's
    value repeated over the evaluations of its batch; the rows before the first value (loop 0, which
    has none) take the first value."""
    values, counts, done = [], [], 0
    for m in run.metrics:
        v = m.get(key, math.nan)
        values.append(v if isinstance(v, float) else math.nan)
        counts.append(max(0, int(m["evaluations"]) - done))
        done = int(m["evaluations"])
    v = np.array(values, dtype=float)
    known = np.flatnonzero(~np.isnan(v))
    if known.size == 0:
        return None
    v[:known[0]] = v[known[0]]
    return np.repeat(v, counts)


def centred_mean(x, window):
    """The centred moving mean of `x` over `window` points, its ends padded with the first and last
    values so that the result has len(x) points (the paper's figures smooth this way)."""
    x = np.asarray(x, dtype=float)
    if window <= 1 or x.size == 0:
        return x
    padded = np.concatenate([np.full(window // 2, x[0]), x, np.full(window // 2 - 1 + window % 2, x[-1])])
    c = np.concatenate([[0.0], np.cumsum(padded)])
    return (c[window:] - c[:-window]) / window


def paper_mixing_ratio(runs, window=10000, key="mixing_ratio"):
    """(evaluations, mean, std): the mixing ratio as the paper's figures draw it. Per evaluation, the
    mean and standard deviation over the seeds that reached it of each run's per_evaluation() value;
    then a centred moving mean over `window` evaluations (the band's edges, clipped to [0, 1],
    smoothed alike; std returned as half the smoothed band). None when no run has a value."""
    series = [s for s in (per_evaluation(r, key) for r in runs) if s is not None]
    if not series:
        return None
    n = max(len(s) for s in series)
    stack = np.full((len(series), n), np.nan)
    for i, s in enumerate(series):
        stack[i, :len(s)] = s
    reached = (~np.isnan(stack)).sum(axis=0)
    total = np.nansum(stack, axis=0)
    mean = total / reached
    std = np.sqrt(np.nansum((stack - mean) ** 2, axis=0) / reached)
    low, high = (centred_mean(np.clip(b, 0, 1), window) for b in (mean - std, mean + std))
    return np.arange(1, n + 1), centred_mean(mean, window), (high - low) / 2
