"""qdplot: figures of qdrun run directories (the PoMS paper's figures, for any task).

Takes run directories, or roots holding <name>/seed-<seed>/ runs, groups the runs by environment
and algorithm (from each run's config.toml) and writes, as PNG and SVG:

  coverage-<env>            coverage (% of all cells) against evaluations: median and 25-75 % band
                            over seeds, one line per algorithm, markers at loop boundaries; the
                            mixing ratio below
  qd-<env>                  for tasks with a fitness: QD score, max and mean fitness against
                            evaluations, median and 25-75 % band over seeds
  map-<env>-<alg>           the archive's occupied cells, laid out from the run's grid.toml (any
                            descriptor), dimension 0 to the right; a 2-D CVT archive as its
                            Voronoi cells
  map-<env>-<alg>-fitness   the elites' fitness on the same grid, when it varies (--color)
  traces-<env>-<alg>        every elite's trajectory (its trace's main columns), from qdrun --replay
  latents-<env>-<alg>       the dataset in the representation's latent space, from qdrun --latents
  losses-<env>-<alg>        autoencoder training and test loss per epoch, every loop

Maps, traces, latents and losses use one run per group: the seed with the median final coverage.
qdplot.json in the output directory lists every file written with its pixel size and runs;
--dump-data adds <figure>.json files holding the numbers plotted. Algorithm names, colours and
markers come from algorithms.toml beside this script, trajectory column names and the paper's map
orientation from environments.toml.

Runs with Debian's matplotlib (scripts/install-deps.sh --plots): the shebang is /usr/bin/python3 on
purpose, a pyenv or virtualenv python3 on PATH does not see Debian's packages."""
import argparse
import sys

from . import ToolError, figures, runs as runs_mod
from .figures.output import Output
from .qdrun import find_qdrun

KINDS = list(figures.KINDS)


def parser():
    ap = argparse.ArgumentParser(prog="qdplot", description=__doc__.split("\n\n")[0],
                                 epilog="Files: see share/README.md. Example: qdplot runs/ -o figures/",
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", help="run directories, or roots holding <name>/seed-<seed>/ runs")
    ap.add_argument("-o", "--output", default="figures", help="output directory (default: figures)")
    ap.add_argument("--kinds", default=",".join(KINDS), help=f"figures to make (default: {','.join(KINDS)})")
    ap.add_argument("--color", default=",".join(figures.COLORS),
                    help="maps to draw: occupancy (elites in one colour), fitness (the elites' fitness, when it "
                         "varies), or both (default: occupancy,fitness)")
    ap.add_argument("--formats", default="png,svg", help="png and/or svg (default: png,svg)")
    ap.add_argument("--dpi", type=int, default=100, help="PNG resolution; pixels = inches x dpi (default: 100)")
    ap.add_argument("--compact", action="store_true", help="8-bit palette PNGs (a third of the size; for results/)")
    ap.add_argument("--dump-data", action="store_true", help="also write <figure>.json with the numbers plotted")
    ap.add_argument("--qdrun", help="qdrun executable for traces and latents (default: $QDRUN, <prefix>/bin, "
                    "PATH, then build/bin of the source tree)")
    return ap


def split(text, known, what, ap):
    items = [k for k in text.split(",") if k]
    for k in items:
        if k not in known:
            ap.error(f"unknown {what} '{k}' ({', '.join(known)})")
    return items


def main(argv=None):
    ap = parser()
    args = ap.parse_args(argv)
    kinds = split(args.kinds, KINDS, "kind", ap)
    formats = split(args.formats, ["png", "svg"], "format", ap)
    colors = split(args.color, list(figures.COLORS), "color", ap)
    try:
        plot(args.runs, args.output, kinds, formats, args.dpi, args.dump_data, args.qdrun, colors, args.compact)
    except ToolError as e:
        sys.exit(f"qdplot: {e}")


def plot(paths, output, kinds, formats=("png", "svg"), dpi=100, dump=False, qdrun=None,
         colors=figures.COLORS, compact=False):
    runs = runs_mod.find_runs(paths)
    for r in runs:
        if not r.metrics:
            print(f"qdplot: skipping {r.path}: metrics.csv has no rows", file=sys.stderr)
    groups = runs_mod.group(runs)
    out = Output(output, formats, dpi, dump, compact)
    needs_qdrun = [k for k in kinds if figures.KINDS[k][1]]
    exe = find_qdrun(qdrun) if needs_qdrun else None
    if needs_qdrun and not exe:
        print(f"qdplot: qdrun not found (--qdrun or $QDRUN): no {' or '.join(needs_qdrun)} figures", file=sys.stderr)
    for env, algs in sorted(groups.items()):
        for kind in kinds:
            if figures.KINDS[kind][0] == "environment":
                figures.draw(kind, out, (env, algs))
        for alg, rs in sorted(algs.items()):
            example = runs_mod.median_run(rs)
            for kind in kinds:
                scope, needs = figures.KINDS[kind]
                if scope == "run" and (exe or not needs):
                    figures.draw(kind, out, example, exe, colors)
    out.finish()
    return out
