#!/usr/bin/python3
"""Checks for digitize.py.
Known-answer test: redraw the digitised curves in the paper's style (same draw order, full-colour lines
with markers every 20 000 evaluations, alpha-0.2 bands, grids, ticks, 600 dpi), digitise the redrawn
figures and compare with the curves they were drawn from. With --overlay DIR: only draw the digitised
curves over the original figures (visual check).   /usr/bin/python3 selfcheck.py [SOURCE] [--overlay DIR]"""
import argparse, os, tempfile
import numpy as np
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt
from matplotlib.ticker import MultipleLocator
import digitize as D


def redraw(out, order, path, xmax, ystep):
    fig, ax = plt.subplots(2, 1, figsize=(5.2, 5.2), gridspec_kw={'height_ratios': [3, 1]})
    for k in order:
        for p in (0, 1):
            if (k, p) not in out:
                continue
            x, y = out[(k, p)]['x'], out[(k, p)]['y']
            spread = 0.08 * y if p == 0 else 0.05
            ax[p].fill_between(x, y - spread, y + spread, color='#' + D.ALGOS[k], alpha=0.2)
            if p == 0 and k in D.SHAPES:
                xl = np.arange(0, x[-1], 20000.0)
                xl = xl[xl >= x[0]]
                ax[p].scatter(xl, np.interp(xl, x, y), s=18, color='#' + D.ALGOS[k], marker=D.SHAPES[k])
            ax[p].plot(x, y, color='#' + D.ALGOS[k], lw=2)
    for p, a in enumerate(ax):
        a.set_xlim(-0.05 * xmax, xmax)
        a.xaxis.set_major_locator(MultipleLocator(0.5e6))
        a.xaxis.set_minor_locator(MultipleLocator(1e5))
        a.yaxis.set_major_locator(MultipleLocator(ystep if p == 0 else 0.5))
        if p == 1:
            a.yaxis.set_minor_locator(MultipleLocator(0.1))
            a.set_ylim(-0.03, 1.03)
        a.grid(which='minor', alpha=0.2 if p == 0 else 0.5, linestyle='-' if p == 0 else ':')
        a.grid(which='major', alpha=0.5)
    ax[0].set_ylim(bottom=-0.03 * ax[0].get_ylim()[1])
    ax[0].set_xticklabels([])
    plt.subplots_adjust(hspace=0.1)
    fig.savefig(path, dpi=600, bbox_inches='tight')
    plt.close(fig)


def overlay(img, out, path):
    """Digitised curves (black dashes; white where hidden) and placed loop markers (+) on the figure."""
    fig = plt.figure(figsize=(img.shape[1] / 100, img.shape[0] / 100), dpi=100)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.imshow(img.astype(np.uint8))
    for r in out.values():
        ax.plot(r['col'], r['row'], 'k--', lw=1.2, dashes=(3, 2))
        ax.plot(r['col'], np.where(r['vis'], np.nan, r['row']), color='w', lw=1.2)
        ax.plot(r['peaks'], np.interp(r['peaks'], r['col'], r['row']), 'k+', ms=12)
    ax.axis('off')
    fig.savefig(path)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('source', nargs='?', default=D.MIRROR)
    ap.add_argument('--overlay', help='write overlay_<env>.png here instead of running the known-answer test')
    args = ap.parse_args()
    imgs = {env: D.load(args.source, D.FIGURES[env][0]) for env in D.FIGURES}
    order = D.draw_order([D.colours(img, D.inside(D.find_panels(img)[1][0])) for img in imgs.values()])[0]
    if args.overlay:
        os.makedirs(args.overlay, exist_ok=True)
        for env, img in imgs.items():
            out = D.digitise(img, *D.FIGURES[env][1:], order, [])
            overlay(img, out, os.path.join(args.overlay, 'overlay_%s.png' % env))
        return
    tmp = tempfile.mkdtemp(prefix='paper-curves-selfcheck-')
    print('redrawn figures in', tmp)
    for env, (suffix, xstep, ystep) in D.FIGURES.items():
        truth = D.digitise(imgs[env], xstep, ystep, order, [])
        xmax = 2e6 if 'BIPEDAL' in suffix else 1e6
        redraw(truth, order, os.path.join(tmp, 'bd_coverage__nolegend_bdpercent_%s.png' % suffix), xmax, ystep)
        report = []
        got = D.digitise(D.load(tmp, suffix), xstep, ystep, order, report)
        print(env + '\n' + '\n'.join(l for l in report if 'residual' in l or 'loop' in l))
        for (k, p), t in truth.items():
            if (k, p) not in got:
                print('  %-16s %s: NOT FOUND' % (k, 'coverage' if p == 0 else 'ratio'))
                continue
            g = got[(k, p)]
            x = np.arange(max(t['x'][0], g['x'][0]), min(t['x'][-1], g['x'][-1]), 5000.0)
            err = np.abs(np.interp(x, g['x'], g['y']) - np.interp(x, t['x'], t['y']))
            hid = np.interp(x, g['x'], g['vis'].astype(float)) < 0.5
            unit = '%' if p == 0 else ''
            print('  %-16s %-8s |error| median %.3f%s, 95th pct %.3f%s, max %.3f%s at x=%.0f; hidden %.0f%% of x; '
                  'covered %.0f-%.0f of %.0f-%.0f' % (k, 'coverage' if p == 0 else 'ratio', np.median(err), unit,
                  np.percentile(err, 95), unit, err.max(), unit, x[err.argmax()], 100 * hid.mean(),
                  g['x'][0], g['x'][-1], t['x'][0], t['x'][-1]))


if __name__ == '__main__':
    main()
