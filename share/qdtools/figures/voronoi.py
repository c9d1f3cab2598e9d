"""map-<env>-<alg> and map-<env>-<alg>-fitness of a CVT archive (grid.toml kind = "cvt") with two
descriptor dimensions: its Voronoi cells, each coloured as the grid maps colour theirs (white empty,
blue elite; or the elite's fitness).

The cells are drawn as a raster of the axes' own pixels, each pixel the colour of the cell of its
centre: the nearest centroid (Euclidean, in the descriptor's values, as qdrun assigns cells), found
exactly with numpy alone (nearest_centroid: no scipy). Cell borders are drawn in grey where cells
are large enough to show them."""
import math

import matplotlib.colors
import numpy as np
from matplotlib.patches import Patch

from .common import legend_below, run_title, slug

ELITE = "tab:blue"
FITNESS_CMAP = "viridis"
TILE = 16              # pixels per side of the tiles nearest_centroid searches together
BORDER_PIXELS = 60     # draw cell borders when a cell covers at least this many pixels on average
MAX_SCALE_RATIO = 4.0  # draw both dimensions to scale unless one range is more than this times the other


def nearest_centroid(points, centroids, tile=None):
    """The index of the nearest centroid of every point (points x dims, centroids x dims; squared
    Euclidean distance, the lowest index on ties), the same as the brute-force argmin. With `tile`
    (an array giving each point's tile id), the centroids searched for a tile are those within
    d0 + 2h of the tiles' centre, where d0 is the centre's nearest distance and h the tile's
    half-diagonal: no nearer centroid can lie outside that ball."""
    points, centroids = np.asarray(points, float), np.asarray(centroids, float)
    out = np.empty(len(points), dtype=np.int64)
    groups = [np.arange(len(points))] if tile is None else \
        np.split(np.argsort(tile, kind="stable"), np.cumsum(np.bincount(tile))[:-1])
    for idx in groups:
        if idx.size == 0:
            continue
        p = points[idx]
        lo, hi = p.min(axis=0), p.max(axis=0)
        centre, half = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
        d = np.sqrt(((centroids - centre) ** 2).sum(axis=1))
        candidates = np.nonzero(d <= d.min() + 2 * half + 1e-9 * (1 + d.min()))[0]  # ascending: ties as argmin
        sq = ((p[:, None, :] - centroids[None, candidates, :]) ** 2).sum(axis=2)
        out[idx] = candidates[np.argmin(sq, axis=1)]
    return out


def raster_cells(grid, width, height):
    """The cell of every pixel of a width x height raster over the grid's value box (row 0 at the
    bottom), by its centre."""
    (x0, y0), (x1, y1) = grid.lower[:2], grid.upper[:2]
    xs = x0 + (np.arange(width) + 0.5) * (x1 - x0) / width
    ys = y0 + (np.arange(height) + 0.5) * (y1 - y0) / height
    px, py = np.meshgrid(xs, ys)
    points = np.column_stack([px.ravel(), py.ravel()])
    cols, rows = np.arange(width) // TILE, np.arange(height) // TILE
    tiles = (rows[:, None] * (cols.max() + 1) + cols[None, :]).ravel()
    return nearest_centroid(points, grid.centroids, tiles).reshape(height, width)


def plot(out, run, grid, archive, color):
    """Draws one map of a 2-D CVT archive (`color`: occupancy or fitness)."""
    cells, fitness = archive.cells, color == "fitness"
    fig = out.figure("map-voronoi")
    ax = fig.subplots(1, 1)
    (x0, y0), (x1, y1) = grid.lower[:2], grid.upper[:2]
    ratio = (x1 - x0) / (y1 - y0)
    to_scale = 1 / MAX_SCALE_RATIO <= ratio <= MAX_SCALE_RATIO
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal" if to_scale else "auto")
    height_in = fig.get_size_inches()[1]
    fig.subplots_adjust(left=0.12, right=0.86 if fitness else 0.95, top=1 - 0.55 / height_in, bottom=1.2 / height_in)
    ax.apply_aspect()
    box = ax.get_position()
    width_px, height_px = fig.get_size_inches() * out.dpi
    w, h = max(2, round(box.width * width_px)), max(2, round(box.height * height_px))
    labels = raster_cells(grid, w, h)
    values = np.full(grid.cells, np.nan)
    if fitness:
        values[cells] = archive.objective
        vmin, vmax = float(np.nanmin(archive.objective)), float(np.nanmax(archive.objective))
        cmap = matplotlib.colormaps[FITNESS_CMAP].copy()
        norm = matplotlib.colors.Normalize(vmin, vmax)
    else:
        values[cells] = 1.0
        cmap = matplotlib.colors.ListedColormap([ELITE])
        norm = matplotlib.colors.Normalize(0.0, 1.0)
    cmap.set_bad("white")
    image = ax.imshow(values[labels], origin="lower", extent=(x0, x1, y0, y1), cmap=cmap, norm=norm,
                      interpolation="nearest", aspect=ax.get_aspect(), resample=False)
    borders = w * h / grid.cells >= BORDER_PIXELS
    if borders:  # a pixel whose right or upper neighbour lies in another cell
        edge = np.zeros(labels.shape, dtype=bool)
        edge[:, :-1] |= labels[:, :-1] != labels[:, 1:]
        edge[:-1, :] |= labels[:-1, :] != labels[1:, :]
        overlay = np.zeros(labels.shape + (4,))
        overlay[edge] = (0.6, 0.6, 0.6, 1.0)
        ax.imshow(overlay, origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest",
                  aspect=ax.get_aspect(), resample=False)
    names = grid.names
    for axis_label, d in ((ax.set_xlabel, 0), (ax.set_ylabel, 1)):
        axis_label(f"{names[d]} ([{grid.lower[d]:g}, {grid.upper[d]:g}])", fontsize=8)
    ax.tick_params(labelsize=7)
    what = "fitness of the elites" if fitness else "occupied cells"
    fig.suptitle(run_title(run, f"{what}, {run.coverage_text(len(cells))}"), fontsize=10)
    caption = (f"CVT archive: {grid.cells} Voronoi cells of the centroids in centroids.csv (nearest centroid per "
               f"pixel{', borders in grey' if borders else ''})" + ("" if to_scale else "; axes not to scale"))
    fig.text(0.5, 0.095, caption, ha="center", fontsize=7)
    handles = [Patch(facecolor="white", edgecolor="0.5", linewidth=0.5)]
    legend = [f"empty cell ({grid.cells - len(cells)})"]
    data = {"run": str(run.path), "kind": "cvt", "elites": int(len(cells)), "cells": grid.cells, "names": names,
            "lower": grid.lower[:2], "upper": grid.upper[:2], "color": color, "raster": [w, h], "borders": borders,
            "to_scale": to_scale, "epoch_cap": run.epoch_cap,
            "filled_pixels": int(np.count_nonzero(~np.isnan(values[labels])))}
    if fitness:
        cax = fig.add_axes([box.x1 + 0.02, box.y0, 0.025, box.height])  # beside: the cells' axes keep their pixels
        bar = fig.colorbar(image, cax=cax)
        bar.set_label("fitness (archive.csv objective)", fontsize=8)
        bar.ax.tick_params(labelsize=7)
        data.update(vmin=vmin, vmax=vmax, cmap=FITNESS_CMAP)
    else:
        handles.insert(0, Patch(facecolor=ELITE))
        legend.insert(0, f"elite ({len(cells)})")
    legend_below(fig, handles, legend, ncol=2, fontsize=8)
    fig.canvas.draw()
    box = ax.get_position()
    data["axes"] = [{"bbox": [box.x0 * width_px, box.y0 * height_px, box.x1 * width_px, box.y1 * height_px]}]
    name = f"map-{slug(run.env)}-{slug(run.algorithm)}" + ("-fitness" if fitness else "")
    out.save(fig, name, "map", data, [run], environment=run.env, algorithm=run.algorithm)


def drawable(grid):
    """Why a CVT archive cannot be drawn as a map, or None when it can."""
    if grid.dimensions != 2:
        return f"a CVT archive over {grid.dimensions} dimensions (qdplot draws those of 2)"
    if grid.centroids is None:
        return "its centroids.csv is missing"
    if not all(math.isfinite(v) for v in grid.lower + grid.upper) or any(
            u <= l for l, u in zip(grid.lower, grid.upper)):
        return "grid.toml's lower and upper bounds are not a box"
    return None
