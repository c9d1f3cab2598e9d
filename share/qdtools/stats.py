"""Statistics over seeds as the reference's plots compute them: numpy's 'nearest' percentiles, the
coverage curve as a step function of evaluations, moving means."""
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


def moving_mean(values, window):
    """The mean of the last `window` non-NaN values up to each position (NaN where there are none)."""
    v = np.asarray(values, dtype=float)
    if window <= 1 or v.size == 0:
        return v
    out = np.full(v.size, np.nan)
    for i in range(v.size):
        seg = v[max(0, i - window + 1):i + 1]
        seg = seg[~np.isnan(seg)]
        if seg.size:
            out[i] = seg.mean()
    return out


def mean(values):
    values = [v for v in values if not (isinstance(v, float) and math.isnan(v))]
    return sum(values) / len(values) if values else math.nan
