"""latents-<env>-<alg>: the dataset's latent codes (qdrun --latents RUN) in their two highest-variance
dimensions, coloured by two of the grid's dimensions (the first, and the largest of the others).
Runs with a representation only."""
import numpy as np

from .. import qdrun as qdrun_mod
from ..runs import read_csv
from .common import run_title, slug


def colourings(grid, cells):
    """(name, values) pairs to colour the points by: the bins of the grid's first dimension and of
    its largest other one (a CVT's: the first two coordinates of the cell's centroid; the cell index
    without a grid)."""
    if grid is None:
        return [("cell", cells)]
    if grid.is_cvt:
        return [(f"{grid.names[d]} of the cell's centroid", grid.centroids[cells, d])
                for d in range(min(2, len(grid.names)))]
    bins = grid.unravel(cells)
    if len(grid.shape) == 1:
        return [(f"{grid.names[0]} bin", bins[0])]
    other = max(range(1, len(grid.shape)), key=lambda d: (grid.shape[d], -d))
    return [(f"{grid.names[0]} bin", bins[0]), (f"{grid.names[other]} bin", bins[other])]


def plot(out, run, qdrun):
    checkpoint = run.path / "checkpoint.bin"
    if run.representation == "none":
        return
    if not checkpoint.exists():
        print(f"qdplot: no latent codes for {run.path}: it has no checkpoint.bin (the representation's state)")
        return
    csv = out.dir / "data" / f"latents-{slug(run.env)}-{slug(run.algorithm)}-seed-{run.seed}.csv"
    if qdrun_mod.make(qdrun, ["--latents", run.path, "--output", csv], csv, [checkpoint]):
        return
    rows = read_csv(csv)
    header = list(rows[0]) if rows else []
    zcols = [k for k in header if k.startswith("z_")]
    if not rows or not zcols:
        print(f"qdplot: no latent codes for {run.path}: {csv} holds none")
        return
    cells = np.array([int(r["cell"]) for r in rows], dtype=np.int64)
    z = np.array([[r[k] for k in zcols] for r in rows])
    var = z.var(axis=0)
    top = [int(i) for i in np.argsort(-var, kind="stable")[:2]]
    if len(top) < 2:
        top = top * 2
    fig = out.figure("latents")
    axes = np.atleast_1d(fig.subplots(1, len(colourings(run.grid, cells))))
    for ax, (name, values) in zip(axes, colourings(run.grid, cells)):
        sc = ax.scatter(z[:, top[0]], z[:, top[1]], c=values, s=4 if len(cells) > 2000 else 10, cmap="viridis",
                        linewidths=0)
        fig.colorbar(sc, ax=ax, label=name)
        ax.set_xlabel(f"{zcols[top[0]]} (variance {var[top[0]]:.3g})")
        ax.set_ylabel(f"{zcols[top[1]]} (variance {var[top[1]]:.3g})")
        ax.grid(alpha=0.3)
    fig.suptitle(run_title(run, f"dataset of {len(cells)} policies in the latent space (two highest-variance "
                                "dimensions; one point per policy)"), fontsize=10)
    fig.subplots_adjust(left=0.07, right=0.97, top=0.87, bottom=0.12, wspace=0.3)
    out.save(fig, f"latents-{slug(run.env)}-{slug(run.algorithm)}", "latents",
             {"run": str(run.path), "entries": int(len(cells)), "dimensions": [zcols[i] for i in top],
              "variances": [float(var[i]) for i in top], "source": str(csv), "epoch_cap": run.epoch_cap}, [run],
             environment=run.env, algorithm=run.algorithm)
