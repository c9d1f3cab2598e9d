"""map-<env>-<alg> (occupancy) and map-<env>-<alg>-fitness: the final archive on the descriptor's
grid, laid out from the run's grid.toml alone, so any descriptor is drawn with no change here.

Layout (layout()): dimension 0 goes to the right. A 3-D grid with at most MAX_PANELS bins in
dimension 0 is one panel per bin of dimension 0 (titled with the bin's label from grid.toml, if
the descriptor names its bins), dimension 1 to the right and dimension 2 up in each; any other grid
is one image whose columns nest dimensions 0, 2, 4, ... and whose rows nest 1, 3, 5, ..., the
earlier dimension outside (2-D: columns = dimension 0, rows = dimension 1; 1-D: one row).
share/environments.toml may name the dimensions to draw to the right for a descriptor whose
dimensions are listed rows first (the paper's). Cells are square, unless the image would be more
than MAX_RATIO times wider than high (or higher than wide): it is then stretched to that ratio.
A CVT archive (grid.toml kind = "cvt") is drawn by voronoi.py instead, as its Voronoi cells."""
import math

import matplotlib.colors
import numpy as np
from matplotlib.patches import Patch

from .. import ToolError, tables
from . import voronoi
from .common import legend_below, run_title, slug

MAX_PANELS = 36
MAX_RATIO = 8.0
ELITE = "tab:blue"
FITNESS_CMAP = "viridis"


def layout(grid, descriptor_type=None):
    """{"layout": "panels"|"nested", "panel": dim or None, "horizontal": [dims], "vertical": [dims]},
    outer dimension first."""
    shape, n = grid.shape, len(grid.shape)
    chosen = tables.environments().horizontal(descriptor_type, grid.names) if descriptor_type else None
    if n == 3 and shape[0] <= MAX_PANELS:
        inner = [1, 2]
        h = [d for d in (chosen or []) if d in inner][:1] or [1]
        return {"layout": "panels", "panel": 0, "horizontal": h, "vertical": [d for d in inner if d not in h]}
    if n == 1:
        return {"layout": "nested", "panel": None, "horizontal": [0], "vertical": []}
    h = chosen if chosen else list(range(0, n, 2))
    return {"layout": "nested", "panel": None, "horizontal": h, "vertical": [d for d in range(n) if d not in h]}


def position(bins, shape, dims):
    """Column (or row) of every cell in an image: mixed radix over `dims`, the first outermost."""
    pos = np.zeros(len(bins[0]) if bins else 0, dtype=np.int64)
    for d in dims:
        pos = pos * shape[d] + bins[d]
    return pos


def has_fitness(archive):
    """Whether the archive's fitness (objective) varies, so a fitness map says something."""
    f = archive.objective[np.isfinite(archive.objective)] if archive is not None else np.array([])
    return f.size > 1 and float(f.max() - f.min()) > 0


def size_key(ratio):
    return "map-very-wide" if ratio >= 8 else "map-wide" if ratio >= 2 else "map-tall" if ratio <= 0.5 \
        else "map-square"


def plot(out, run, colors=("occupancy", "fitness")):
    archive = run.archive()
    if archive is None:
        print(f"qdplot: no map for {run.path}: it has no archive.csv (a run that has not finished, or a study "
              "that does not keep archives)")
        return
    grid = run.grid
    if grid is None:
        print(f"qdplot: no map for {run.path}: it has no grid.toml (qdrun writes one since 2026-12-03; run it "
              "again, or --resume it once, to get one)")
        return
    cells = archive.cells
    if cells.size and (cells.min() < 0 or cells.max() >= grid.cells):
        raise ToolError(f"{run.path / 'archive.csv'}: a cell index outside the {grid.cells} cells of grid.toml")
    painter = draw
    if grid.is_cvt:
        why = voronoi.drawable(grid)
        if why:
            print(f"qdplot: no map for {run.path}: {why}")
            return
        painter = voronoi.plot
    if "occupancy" in colors:
        painter(out, run, grid, archive, "occupancy")
    if "fitness" in colors:
        if has_fitness(archive):
            painter(out, run, grid, archive, "fitness")
        else:
            print(f"qdplot: no fitness map for {run.path}: every elite has the same fitness (objective)")


def draw(out, run, grid, archive, color):
    shape, names = grid.shape, grid.names
    cells = archive.cells
    bins = grid.unravel(cells)
    lay = layout(grid, run.descriptor_type)
    h, v = lay["horizontal"], lay["vertical"]
    ncols = math.prod(shape[d] for d in h)
    nrows = math.prod(shape[d] for d in v) if v else 1
    col, row = position(bins, shape, h), position(bins, shape, v) if v else np.zeros(len(cells), dtype=np.int64)
    fitness = color == "fitness"
    if fitness:
        values = archive.objective
        vmin, vmax = float(np.nanmin(values)), float(np.nanmax(values))
        cmap = matplotlib.colormaps[FITNESS_CMAP].copy()
        norm = matplotlib.colors.Normalize(vmin, vmax)
    else:
        values = np.ones(len(cells))
        vmin, vmax = 0.0, 1.0
        cmap = matplotlib.colors.ListedColormap([ELITE])
        norm = matplotlib.colors.Normalize(0.0, 1.0)
    cmap.set_bad("white")
    what = "fitness of the elites" if fitness else "occupied cells"
    title = run_title(run, f"{what}, {run.coverage_text(len(cells))}")
    data = {"run": str(run.path), "elites": int(len(cells)), "cells": run.cells, "shape": shape, "names": names,
            "labels": grid.labels, "layout": lay["layout"], "panel_dim": lay["panel"], "horizontal": h,
            "vertical": v, "color": color, "index_space": run.index_space, "epoch_cap": run.epoch_cap, "axes": []}
    if fitness:
        data.update(vmin=vmin, vmax=vmax, cmap=FITNESS_CMAP)
    if lay["layout"] == "panels":
        panels = shape[0]
        img = np.full((panels, nrows, ncols), np.nan)
        img[bins[0], row, col] = values
        fig = out.figure("map-panels")
        pc = min(panels, 6)
        pr = math.ceil(panels / pc)
        axes = fig.subplots(pr, pc, squeeze=False)
        used = []
        for k, ax in enumerate(axes.flat):
            if k >= panels:
                ax.axis("off")
                continue
            image = ax.imshow(img[k], origin="lower", cmap=cmap, norm=norm, interpolation="nearest", aspect="equal")
            filled = int(np.count_nonzero(~np.isnan(img[k])))
            ax.set_title(f"{names[0]} {grid.bin_label(0, k)} ({filled})", fontsize=7, pad=2)
            bottom, left = k + pc >= panels, k % pc == 0
            value_ticks(ax.xaxis, grid, h[0], label=bottom, most=4)
            value_ticks(ax.yaxis, grid, v[0], label=left, most=4)
            if bottom:
                ax.set_xlabel(names[h[0]], fontsize=7, labelpad=1)
            if left:
                ax.set_ylabel(names[v[0]], fontsize=7, labelpad=1)
            data["axes"].append({"panel": k, "rows": nrows, "cols": ncols})
            used.append(ax)
        data["per_panel"] = [int(np.count_nonzero(~np.isnan(img[k]))) for k in range(panels)]
        data["filled"] = int(np.count_nonzero(~np.isnan(img)))
        fig.text(0.5, 0.065, f"one panel per bin of {names[0]} (its label and elites above each); in each, "
                 f"{names[h[0]]} to the right ({grid.describe_dimension(h[0])}) and {names[v[0]]} up "
                 f"({grid.describe_dimension(v[0])})", ha="center", fontsize=8)
        fig.subplots_adjust(left=0.06, right=0.9 if fitness else 0.98, top=0.86, bottom=0.16, wspace=0.3,
                            hspace=0.55)
    else:
        img = np.full((nrows, ncols), np.nan)
        img[row, col] = values
        ratio = ncols / nrows
        shown = min(max(ratio, 1 / MAX_RATIO), MAX_RATIO)
        fig = out.figure(size_key(shown))
        ax = fig.subplots(1, 1)
        image = ax.imshow(img, origin="lower", cmap=cmap, norm=norm, interpolation="nearest", aspect=ratio / shown)
        data["axes"].append({"panel": None, "rows": nrows, "cols": ncols})
        data["filled"] = int(np.count_nonzero(~np.isnan(img)))
        if shown != ratio:
            data["stretched"] = round(ratio / shown, 3)
        captions = []
        for dims, axis, line, label, what in ((h, ax.xaxis, ax.axvline, ax.set_xlabel, "columns"),
                                              (v, ax.yaxis, ax.axhline, ax.set_ylabel, "rows")):
            if not dims:
                axis.set_ticks([])
                label("(one row)", fontsize=7)
                continue
            short, full = nested_ticks(axis, line, grid, dims)
            label(short, fontsize=7)
            if len(dims) > 1:
                captions.append(f"{what}: {full}")
        if shown != ratio:
            captions.append(f"cells drawn {ratio / shown:.2g}x higher than wide" if ratio > 1 else
                            f"cells drawn {shown / ratio:.2g}x wider than high")
        if captions:
            fig.text(0.5, 0.095, "; ".join(captions), ha="center", fontsize=7, wrap=True)
        used = [ax]
        height = fig.get_size_inches()[1]  # room below for the axis label (two lines) and the legend
        fig.subplots_adjust(left=0.1, right=0.88 if fitness else 0.97, top=1 - 0.55 / height, bottom=1.25 / height)
    handles = [Patch(facecolor="white", edgecolor="0.5", linewidth=0.5)]
    labels = [f"empty cell ({grid.cells - len(cells)})"]
    if fitness:
        bar = fig.colorbar(image, ax=used, fraction=0.03, pad=0.02)
        bar.set_label("fitness (archive.csv objective)", fontsize=8)
    else:
        handles.insert(0, Patch(facecolor=ELITE))
        labels.insert(0, f"elite ({len(cells)})")
    legend_below(fig, handles, labels, ncol=2, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.canvas.draw()  # equal-aspect axes take their final box at draw time
    width, height = fig.get_size_inches() * out.dpi
    for entry, ax in zip(data["axes"], used):  # where each image lies, in pixels from the bottom left
        box = ax.get_position()
        entry["bbox"] = [box.x0 * width, box.y0 * height, box.x1 * width, box.y1 * height]
    name = f"map-{slug(run.env)}-{slug(run.algorithm)}" + ("-fitness" if fitness else "")
    out.save(fig, name, "map", data, [run], environment=run.env, algorithm=run.algorithm)


def value_ticks(axis, grid, d, label=True, most=6):
    """Ticks at bin edges of dimension d, labelled with the dimension's values there (or, for named
    bins, at the bins' centres with their names)."""
    n = grid.shape[d]
    if grid.labels and d < len(grid.labels) and grid.labels[d]:
        step = max(1, math.ceil(n / 12))
        axis.set_ticks(range(0, n, step))
        axis.set_ticklabels([grid.labels[d][k] for k in range(0, n, step)] if label else [], fontsize=6)
        return
    step = max(1, math.ceil(n / (most - 1)))
    edges = list(range(0, n + 1, step))
    axis.set_ticks([e - 0.5 for e in edges])
    width = (grid.upper[d] - grid.lower[d]) / n
    axis.set_ticklabels([f"{grid.lower[d] + e * width:.3g}" for e in edges] if label else [], fontsize=6)


def nested_ticks(axis, line, grid, dims):
    """Ticks of an image axis that nests `dims` (outer first): the outer dimension's values (at bin
    edges) or bin labels, separator lines between its blocks. Returns the axis label and, for a
    nested axis, the full description of its dimensions."""
    shape, names = grid.shape, grid.names
    outer, inner = dims[0], math.prod(shape[d] for d in dims[1:])
    if inner == 1:
        value_ticks(axis, grid, outer)
        text = f"{names[outer]} ({grid.describe_dimension(outer)})"
        return text, text
    step = max(1, math.ceil(shape[outer] / 10))  # at most ~10 labelled blocks
    axis.set_ticks([k * inner + (inner - 1) / 2 for k in range(0, shape[outer], step)])
    axis.set_ticklabels([grid.bin_label(outer, k) for k in range(0, shape[outer], step)], fontsize=6)
    for k in range(1, shape[outer]):  # separators between the outer dimension's blocks
        line(k * inner - 0.5, color="0.8", linewidth=0.3)
    short = f"{names[outer]} bin, then " + ", ".join(names[d] for d in dims[1:])
    full = (f"blocks of {names[outer]} ({grid.describe_dimension(outer)}), inside each " +
            ", ".join(f"{names[d]} ({grid.describe_dimension(d)})" for d in dims[1:]))
    return short, full
