#!/usr/bin/python3
"""Digitise the coverage figures of Rakicevic, Cully & Kormushev, "Policy Manifold Search" (GECCO 2021):
calibrate pixel -> data on the ticks (checked on the grid), extract every median curve and the mixing
ratios, measure the loop-marker spacing, write curves.csv.  /usr/bin/python3 digitize.py [SOURCE] [--out DIR]
SOURCE: a bare git mirror of the authors' repository, or a directory holding the PNGs."""
import argparse, io, itertools, os, subprocess
import numpy as np
import matplotlib.image as mimg

MIRROR = '/work/.mirror/nemanja-rakicevic+policy_manifold_search/repo'
ALGOS = {'PoMS': '1f77b4', 'PoMS-PCA': 'ff7f0e', 'PoMS-no-jacobian': '2ca02c', 'MAPE-DDE': 'd62728',  # legend,
         'MAPE-IsoLineDD': '9467bd', 'MAPE-Iso': '8c564b', 'ps-uniform': 'e377c2', 'ps-glorot': '7f7f7f'}  # 'tab'
RGB = {k: np.array([int(v[i:i + 2], 16) for i in (0, 2, 4)], float) for k, v in ALGOS.items()}
SHAPES = {'PoMS': 'o', 'PoMS-PCA': 's', 'PoMS-no-jacobian': 'X', 'MAPE-DDE': '^'}  # 'ls_mape_' configs: loop markers
RATIO = ['PoMS', 'PoMS-PCA']                                                  # curves of the mixing-ratio panel
# environment -> (figure, x major tick step, coverage y major tick step); the lowest major tick is 0.
FIGURES = {'BipedalWalker': ('BIPEDAL_WALKER_AUGMENTED', 0.5e6, 2.0),
           'BipedalKicker': ('BIPEDAL_KICKER_AUGMENTED', 0.5e6, 10.0),
           'Striker': ('STRIKER_AUGMENTED', 0.5e6, 5.0)}
RATIO_YSTEP = 0.5
TOL, LAYER_COST, MARGIN = 4.0, 1.0, 2.0   # colour matching, in 0-255 RGB distance (see label_pixels)


def load(source, suffix):
    name = 'bd_coverage__nolegend_bdpercent_%s.png' % suffix
    if os.path.isdir(os.path.join(source, 'objects')):                        # bare git mirror
        data = io.BytesIO(subprocess.run(['git', '-C', source, 'show', 'HEAD:img/results/' + name],
                                         check=True, capture_output=True).stdout)
    else:
        data = next((p for p in (os.path.join(source, name), os.path.join(source, 'img/results', name))
                     if os.path.exists(p)), os.path.join(source, name))
    return np.round(mimg.imread(data)[..., :3] * 255)


def runs(v):
    """[start, end) of the True runs of a 1-D boolean array."""
    d = np.diff(np.r_[0, v.astype(np.int8), 0])
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def find_panels(img):
    """Spines are long dark rows/columns: two stacked panels sharing left and right spines. Returns the
    dark mask and per panel (top, bottom, left, right) spines as [start, end) pairs."""
    dark = img.max(2) < 90
    rs, re = runs(dark.sum(1) > 0.6 * dark.shape[1])
    cs, ce = runs(dark.sum(0) > 0.4 * dark.shape[0])
    assert len(rs) == 4 and len(cs) == 2, 'expected two stacked panels, found %d/%d spines' % (len(rs), len(cs))
    return dark, [((rs[i], re[i]), (rs[i + 1], re[i + 1]), (cs[0], ce[0]), (cs[1], ce[1])) for i in (0, 2)]


def inside(panel):
    (_, t1), (b0, _), (_, l1), (r0, _) = panel
    return slice(t1, b0), slice(l1, r0)


def axis_fit(ticks, step):
    """Tick marks (profile of their length along the axis, increasing values first) -> pixel/value fit.
    Long ticks are majors, the lowest major is 0 and minors divide the major step evenly."""
    s, e = runs(ticks > 0)
    centre, depth = (s + e - 1) / 2, np.array([ticks[i:j].max() for i, j in zip(s, e)])
    im = np.flatnonzero(depth > 0.75 * depth.max())
    values = (np.arange(len(centre)) - im[0]) * step / (im[1] - im[0])
    assert np.ptp(np.diff(centre)) < 0.05 * abs(np.diff(centre).mean()), 'uneven ticks: %s' % centre
    a, b = np.polyfit(centre, values, 1)
    return a, b, (values - b) / a, np.abs((values - b) / a - centre).max()


def grid_residual(sub, along, ticks_px):
    """Grid lines = thin runs of neutral-grey columns (along=0) / rows (along=1). Max distance (px) of
    their centres from the tick-calibrated positions."""
    grey = (np.ptp(sub, axis=2) == 0) & (sub[..., 0] > 195) & (sub[..., 0] < 248)
    count = grey.sum(axis=along)
    line = count > 0.25 * grey.shape[along]
    for i, j in zip(*runs(~line)):          # a band over part of a line leaves two slivers: rejoin
        line[i:j] |= 0 < i and j < len(line) and j - i <= 6
    s, e = runs(line)
    centres = [np.average(np.arange(i, j), weights=count[i:j]) for i, j in zip(s, e) if 4 <= j - i <= 16]
    return len(centres), np.abs(np.array(centres)[:, None] - ticks_px[None]).min(1).max()


def calibrate(img, dark, panel, xstep, ystep, report):
    (t0, t1), (b0, b1), (l0, l1), (r0, r1) = panel
    xa, xb, xt, xres = axis_fit(dark[b1:b1 + 40, l0 - 3:r1 + 4].sum(0), xstep)   # ticks below the axis
    xt += l0 - 3
    ya, yb, yt, yres = axis_fit(dark[t0 - 3:b1 + 4, l0 - 40:l0].sum(1)[::-1], ystep)   # left of it
    yt = b1 + 3 - yt
    ngx, gx = grid_residual(img[t1:b0, l1:r0], 0, xt - l1)
    ngy, gy = grid_residual(img[t1:b0, l1:r0], 1, yt - t1)
    report.append('  x: %d ticks, %.1f evaluations/px, tick fit residual %.2f px, %d grid lines within %.2f px; '
                  'right spine at x=%.0f' % (len(xt), xa, xres, ngx, gx, xa * ((r0 + r1 - 1) / 2 - l0 + 3) + xb))
    report.append('  y: %d ticks, %.4g per px, tick fit residual %.2f px, %d grid lines within %.2f px'
                  % (len(yt), ya, yres, ngy, gy))
    # pixel -> data:  x = xa * (col - l0 + 3) + xb,  y = ya * (b1 + 3 - row) + yb
    return (xa, xb - xa * (l0 - 3)), (-ya, yb + ya * (b1 + 3)), xt


def colours(img, box):
    """Distinct colours of img[box]: (rgb, index of each pixel's colour, counts, shape)."""
    code = img[box].reshape(-1, 3).astype(np.int64) @ [65536, 256, 1]      # 1-D keys: fast np.unique
    u, inv, cnt = np.unique(code, return_inverse=True, return_counts=True)
    return np.stack([u >> 16, (u >> 8) & 255, u & 255], 1).astype(float), inv.ravel(), cnt, img[box].shape[:2]


def near(table, c):
    return table[2][np.sqrt(((table[0] - c) ** 2).sum(1)) < 2].sum()


def line_bases(table, names):
    """A line's colours before later bands cover it: full colour (the published PNGs) or, if the image
    says so, the script's alpha 0.5 over white or over its own band (fill, fill + edge)."""
    half = sum(near(table, 0.5 * RGB[k] + 127.5) for k in names) > sum(near(table, RGB[k]) for k in names)
    return {k: [0.5 * RGB[k] + 0.5 * (255 - f * (255 - RGB[k])) for f in (0, 0.2, 0.36)] if half else [RGB[k]]
            for k in names}


def draw_order(tables):
    """Each algorithm's band, markers and line are drawn in turn, so later bands (alpha 0.2) tint earlier
    lines. evidence[a, b] = pixels showing line a under one layer of band b, summed over the figures
    (same experiments, same order); the draw order is the permutation with the most evidence."""
    names, n = list(ALGOS), len(ALGOS)
    ev = np.zeros((n, n))
    for t in tables:
        base = line_bases(t, names)
        ev += [[near(t, 0.8 * base[a][0] + 0.2 * RGB[b]) if a != b else 0 for b in names] for a in names]
    perms = np.array(list(itertools.permutations(range(n))))
    best = perms[sum(ev[perms[:, i], perms[:, j]] for i in range(n) for j in range(i + 1, n)).argmax()]
    against = sum(ev[best[j], best[i]] for i in range(n) for j in range(i + 1, n))
    return [names[k] for k in best], ev.sum(), against


def composite(bases, bands, most=5):
    """`bases` under 0, 1 or 2 layers (fill, edge) of each band in draw order, at most `most` layers,
    rounded like 8-bit blending. Returns (colours, layer counts)."""
    out, layers = np.array(bases, float), np.zeros(len(bases), int)
    for b in bands:
        one = np.round(0.8 * out + 0.2 * b)
        out, layers = np.vstack([out, one, np.round(0.8 * one + 0.2 * b)]), np.r_[layers, layers + 1, layers + 2]
        out, layers = out[layers <= most], layers[layers <= most]
    return out, layers


def label_pixels(table, names, order):
    """Label pixels with the algorithm whose line or marker they show (-1: none or ambiguous). Candidate
    colours: each line under the bands drawn after it; bands over white or grid. A pixel takes the owner
    of least (distance + LAYER_COST per layer: deep band stacks can mimic another line) if that
    candidate is within TOL and every other owner scores at least MARGIN worse."""
    u, inv, _, shape = table
    rank, bases = [order.index(k) for k in names], line_bases(table, names)
    bands = lambda after: [RGB[j] for j in sorted(names, key=order.index) if order.index(j) > after]
    groups = [composite(bases[k], bands(rank[i])) for i, k in enumerate(names)]
    groups.append(composite([[255] * 3, [215] * 3, [239] * 3], bands(-1)))
    cands = np.vstack([g[0] for g in groups]).astype(np.float32)
    penalty = np.concatenate([g[1] for g in groups]) * LAYER_COST
    owner = np.concatenate([[i] * len(g[0]) for i, g in enumerate(groups)])
    cost, dist = np.empty((2, len(u), len(groups)), np.float32)
    for s in range(0, len(u), 1000):                     # |u - c| via a matrix product, in chunks
        uu = u[s:s + 1000].astype(np.float32)
        d = np.sqrt(np.maximum((uu ** 2).sum(1)[:, None] - 2 * uu @ cands.T + (cands ** 2).sum(1)[None], 0))
        for g in range(len(groups)):
            cg = np.where(owner == g, d + penalty, np.inf)
            j = cg.argmin(1)
            cost[s:s + 1000, g], dist[s:s + 1000, g] = cg[np.arange(len(j)), j], d[np.arange(len(j)), j]
    best, srt = cost.argmin(1), np.sort(cost, 1)
    ok = (dist[np.arange(len(u)), best] < TOL) & (srt[:, 1] - srt[:, 0] >= MARGIN) & (best < len(names))
    return np.where(ok, best, -1)[inv].reshape(shape), np.array(rank)[None, :] > np.array(rank)[:, None]


def track(lab, i, later, thick):
    """Per column, the run of label i nearest the curve's previous position (gaps are bridged). A side
    is hidden when a curve drawn later lies beyond its anti-aliased edge. Returns top, bottom, up, down."""
    H, W = lab.shape
    m = lab == i
    near3 = lambda sh: np.any([np.roll(m, sh * k, axis=0) for k in (1, 2, 3)], axis=0)
    m |= near3(1) & near3(-1)                                   # close anti-aliasing seams
    on_top = np.isin(lab, np.flatnonzero(later[i]))
    covered = lambda c, r: len(np.flatnonzero(lab[r, c] >= 0)) > 0 and on_top[r, c][np.flatnonzero(lab[r, c] >= 0)[0]]
    cols = []
    for c in range(W):
        rc = [[a, b, covered(c, np.arange(a - 1, max(a - 5, -1), -1)), covered(c, np.arange(b, min(b + 4, H)))]
              for a, b in zip(*runs(m[:, c])) if b - a >= 2]
        for j in range(len(rc) - 1, 0, -1):      # a later curve crossing this one splits it in two: rejoin
            if rc[j - 1][3] and rc[j][2] and rc[j][0] - rc[j - 1][1] < 3 * thick \
                    and (on_top | (lab < 0))[rc[j - 1][1]:rc[j][0], c].all():
                rc[j - 1][1:] = rc[j][1], rc[j - 1][2], rc[j][3]
                del rc[j]
        cols.append(rc)
    seeds = [c for c in range(W) if len(cols[c]) == 1 and not any(cols[c][0][2:])
             and thick - 2 <= cols[c][0][1] - cols[c][0][0] <= 2 * thick]      # one free line-sized run
    out = np.full((4, W), np.nan)
    if seeds:
        seed = seeds[int(0.9 * (len(seeds) - 1))]                # right part: curves are apart there
        for direction in (range(seed, W), range(seed, -1, -1)):
            prev, plen, since = (cols[seed][0][0] + cols[seed][0][1] - 1) / 2, thick, 0
            for c in direction:
                dist = [max(a - prev, prev - b + 1, 0) + 0.01 * abs((a + b - 1) / 2 - prev) for a, b, _, _ in cols[c]]
                if dist and min(dist) <= 30 + 0.5 * plen + 3 * since:
                    a, b, up, dn = out[:, c] = cols[c][int(np.argmin(dist))]
                    prev = b - 1 - thick / 2 if up > dn else a + thick / 2 if dn > up else (a + b - 1) / 2
                    plen, since = b - a, 0
                else:
                    since += 1
    return out


def running(v, w, fn):
    return fn(np.lib.stride_tricks.sliding_window_view(np.pad(v, w // 2, mode='edge'), w), axis=1)


def curve(tr, thick, marked, widths, w=None):
    """Tracked runs -> centre row per column: the midpoint of free runs; with one side hidden, the free
    edge's outermost value over w (about one marker) moved in by half the curve's full height (marker,
    or line if unmarked). Marked curves with a known marker period w: see below. Then running medians
    of widths[0] px, widths[1] px where hidden (safe for monotone curves). Returns cols, rows, free."""
    top, bot, up, dn = tr
    ok = np.flatnonzero(~np.isnan(top))
    if len(ok) == 0:
        return None
    c = np.arange(ok[0], ok[-1] + 1)
    top, bot, up, dn = (np.interp(c, ok, v[ok]) for v in (top, bot, up, dn))
    gap = np.isin(c, ok, invert=True)
    up, dn = (up > 0) & ~gap, (dn > 0) & ~gap
    free, mid = ~up & ~dn & ~gap, (top + bot) / 2
    flat = free & (np.abs(np.gradient(running(mid, 25, np.mean))) < 0.3)      # steep runs are taller
    height = np.percentile((bot - top + 1)[flat], 90) if marked and flat.sum() > 20 else thick
    w0, w = w, (int(w or 2 * height) | 1) if marked else 1
    one_up, one_dn = up & ~dn, dn & ~up
    mid = np.where(one_up, np.minimum(mid, running(np.where(one_up, bot, -np.inf), w, np.max) - (height - 1) / 2), mid)
    mid = np.where(one_dn, np.maximum(mid, running(np.where(one_dn, top, np.inf), w, np.min) + (height - 1) / 2), mid)
    if marked and w0:
        # Markers make column runs lopsided on slopes (a sawtooth of one period): average one period.
        # Asymmetric shapes (triangles) also shift the average; the envelope (highest top, lowest bottom
        # over a period) is exact on straight flat stretches, so it measures that shift.
        hi, lo = running(np.where(free, top, np.inf), w, np.min), running(np.where(free, bot, -np.inf), w, np.max)
        env, mean = (np.where(np.isfinite(hi), hi, 0) + np.where(np.isfinite(lo), lo, 0)) / 2, running(mid, w, np.mean)
        sel = flat & np.isfinite(hi) & np.isfinite(lo)
        mid = mean - (np.median((mean - env)[sel]) if sel.sum() > 20 else 0)
    rows = running(mid, widths[0], np.median)
    if widths[1] > 1:
        hidden = running((~free).astype(float), 2 * thick + 1, np.max) > 0
        rows = np.where(hidden, running(mid, widths[1], np.median), rows)
    return c, rows, free


def markers(lab, i, trk, thick, shape, grid_cols):
    """Loop markers make the curve's free height periodic (circles, squares, triangles tallest at their
    centre; unions of overlapping X's narrowest). Period: the comb of autocorrelation peaks that scores
    best, or its shortest divisor scoring as well. Markers: height extrema near the teeth of the best-fitting comb, on
    flat stretches only (steep runs are tallest elsewhere). Returns (period px, marker columns) or None."""
    c, rows, free = trk
    height = np.array([((lab[:, x] == i) & (np.abs(np.arange(lab.shape[0]) - r) < 3 * thick)).sum()
                       for x, r in zip(c, rows)], float)
    ok = free & (np.abs(c[:, None] - grid_cols[None]).min(1) >= 6)   # hidden runs and grid lines: no say
    if ok.mean() < 0.3:
        return None
    fill = np.where(ok, height, np.median(height[ok]))
    s = fill - running(fill, 61, lambda v, axis: np.percentile(v, 20, axis=axis))
    s = np.where(ok, (s if shape != 'X' else -s) - s[ok].mean(), 0)
    lags = np.arange(300)                     # autocorrelation over valid pairs (the masks are periodic)
    ac = np.array([np.dot(s[:len(s) - k], s[k:]) / max(np.dot(ok[:len(s) - k], ok[k:]), 1) for k in lags])
    grid = np.arange(8, 120, 0.01)            # comb: mean autocorrelation at the multiples (< 240 px)
    score = np.array([np.interp(np.arange(1, 240 // g + 1) * g, lags, ac).mean() for g in grid]) / ac[0]
    if score.max() < 0.05:
        return None
    # the best comb is the period or a multiple of it: take the shortest divisor that scores as well
    period = min(grid[score.argmax()] / n for n in range(1, 7)
                 if np.interp(grid[score.argmax()] / n, grid, score) >= 0.95 * score.max())
    comb = lambda f: np.interp(np.arange(f, len(s), period), np.arange(len(s)), s).sum()
    phase = max(np.arange(0, period, 0.25), key=comb)
    flat = np.abs(np.gradient(running(rows, 25, np.mean))) < 0.3
    half, found = int(period / 3), []
    for t in np.arange(phase, len(s), period).round().astype(int):
        win = slice(max(t - half, 0), t + half + 1)
        if ok[win].all() and flat[win].all() and np.ptp(s[win]) > 2:
            found.append(win.start + int(np.argmax(s[win])))
    return period, c[found]


def digitise(img, xstep, ystep, order, report):
    """Both panels of one figure -> {(algorithm, panel): dict(x, y, vis, col, row, peaks)}."""
    dark, panels = find_panels(img)
    out = {}
    for p, (panel, names, step) in enumerate(zip(panels, (list(ALGOS), RATIO), (ystep, RATIO_YSTEP))):
        report.append(' %s panel' % ('coverage' if p == 0 else 'mixing-ratio'))
        (xa, xb), (ya, yb), xticks = calibrate(img, dark, panel, xstep, step, report)
        rows0, cols0 = inside(panel)
        lab, later = label_pixels(colours(img, inside(panel)), names, order)
        lens = np.concatenate([np.diff(np.stack(runs(lab[:, x] == i)), axis=0).ravel()
                               for i in range(len(names)) for x in range(0, lab.shape[1], 7)])
        thick = np.bincount(lens[lens > 3]).argmax()              # line width: most common run height
        report.append('  line thickness %d px' % thick)
        widths = (7, 4 * thick + 1) if p == 0 else (3, 1)
        trs = {k: track(lab, i, later, thick) for i, k in enumerate(names)}
        trks = {k: curve(trs[k], thick, p == 0 and k in SHAPES, widths) for k in names}
        got = {k: markers(lab, names.index(k), trks[k], thick, SHAPES[k], xticks - cols0.start)
               for k in names if p == 0 and k in SHAPES and trks[k] is not None}
        period = np.median([g[0] for g in got.values() if g is not None] or [np.nan])
        for k in got:         # redo the marker envelopes over one marker period (median over algorithms)
            trks[k] = curve(trs[k], thick, True, widths, period if period > 0 else None)
        for k, trk in trks.items():
            if trk is None:
                report.append('  %-16s not found' % k)
                continue
            c, rows = trk[0] + cols0.start, trk[1] + rows0.start
            keep = xa * c + xb >= 0                 # the x=0 markers stick out left of the data
            r = out[(k, p)] = dict(x=(xa * c + xb)[keep], y=(ya * rows + yb)[keep], vis=trk[2][keep],
                                   col=c[keep], row=rows[keep], peaks=np.array([]))
            info = '  %-16s visible %3.0f%%' % (k, 100 * r['vis'].mean())
            if got.get(k) is not None:                # spacing, and where markers sit within a loop
                period, r['peaks'] = got[k][0], got[k][1] + cols0.start
                loop, d = xa * period, np.diff(xa * r['peaks'])
                z = np.exp(2j * np.pi * (xa * r['peaks'] + xb) / loop).mean() if len(d) > 2 else 0  # circular mean
                info += '; loop markers every %.2f px = %.0f evaluations' % (period, loop) + (
                    '; %d placed, spacing median %.0f, at x = %.0f mod loop (agreement %.2f)' % (len(d) + 1,
                    np.median(d[d < 1.5 * loop]), np.angle(z) / 2 / np.pi * loop % loop, abs(z)) if len(d) > 2 else '')
            elif k in got:
                info += '; loop markers too hidden to measure'
            report.append(info)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('source', nargs='?', default=MIRROR, help='default: %(default)s')
    ap.add_argument('--out', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'share'), help='directory for paper-curves.csv (share/ of the repository by default)')
    args = ap.parse_args()
    imgs = {env: load(args.source, fig[0]) for env, fig in FIGURES.items()}
    order, evidence, against = draw_order([colours(img, inside(find_panels(img)[1][0])) for img in imgs.values()])
    print('draw order: %s (%d of %d evidence pixels disagree)' % (', '.join(order), against, evidence))
    lines = ['figure,algorithm,quantity,evaluations,value,visibility']
    for env, img in imgs.items():
        report = ['%s (%dx%d px)' % (env, img.shape[1], img.shape[0])]
        out = digitise(img, *FIGURES[env][1:], order, report)
        print('\n'.join(report))
        end = int(np.ceil(max(r['x'][-1] for r in out.values()) / 20000) * 20000)    # the axis end
        budgets = sorted(set(range(10000, 100000, 10000)) | set(range(20000, end + 1, 20000)))
        for (k, p), r in out.items():
            px = r['x'][1] - r['x'][0]
            for e in [e for e in budgets if r['x'][0] <= e <= r['x'][-1] + 6 * px]:   # panel ends ~4 px short
                vis = r['vis'][np.abs(r['x'] - e) <= 5 * px].mean() >= 0.5
                lines.append('%s,%s,%s,%d,%.4g,%s' % (env, k, 'mixing_ratio' if p else 'coverage_percent', e,
                                                     np.interp(e, r['x'], r['y']), 'visible' if vis else 'hidden'))
    with open(os.path.join(args.out, 'paper-curves.csv'), 'w') as f:
        f.write('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
