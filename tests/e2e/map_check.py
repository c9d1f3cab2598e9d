#!/usr/bin/python3
"""Checks qdplot's archive maps pixel by pixel against the run directory alone.

  map_check.py MAP.png [MAP.png ...]

Each MAP.png needs the MAP.json that qdplot --dump-data writes beside it: the run directory it
draws, its layout and where each image lies in the figure. The layout must be the documented one
for the run's grid and descriptor (share/README.md, "Maps": dimension 0 to the right, unless
share/environments.toml names the descriptor's horizontal dimensions), which the tools' unit tests
pin (tests/tools/test_tables.py). The expected picture is computed from the run's archive.csv and
grid.toml: a cell's column mixes the bins of the horizontal dimensions, its row those of the
vertical ones, the first outermost (panels: one per bin of dimension 0). The pixel at the centre of
every cell must show what the archive says: for an occupancy map the elite colour (tab:blue) when
the archive holds the cell and white when it does not; for a fitness map white for an empty cell
and the colour map's colour of the elite's fitness otherwise. A centre under a panel frame or
separator line is skipped (at most 5 % may be), and the PNG must be a real PNG that matplotlib
wrote (signature, and more than a few colours)."""
import json
import sys
from pathlib import Path

import matplotlib
import matplotlib.image
import numpy as np

from figure_check import runs

from qdtools.figures import maps

BLUE = (0x1F, 0x77, 0xB4)
WHITE = (0xFF, 0xFF, 0xFF)


def near(colour, reference, tolerance=40):
    """Within `tolerance` in every channel: a faint separator line drawn across a small cell (light
    grey, partly transparent after anti-aliasing) does not change what the cell shows."""
    return max(abs(c - r) for c, r in zip(colour, reference)) <= tolerance


def check(png):
    failures = []
    if png.read_bytes()[:8] != b"\x89PNG\r\n\x1a\n":
        return [f"{png}: not a PNG"]
    dump = json.loads(png.with_suffix(".json").read_text())
    run = runs.Run(dump["run"])
    grid, archive = run.grid, run.archive()
    layout = maps.layout(grid, run.descriptor_type)
    declared = {"layout": dump["layout"], "panel": dump["panel_dim"], "horizontal": dump["horizontal"],
                "vertical": dump["vertical"]}
    if declared != layout:
        failures.append(f"{png}: drawn as {declared}, the documented layout of this grid is {layout}")
    filled = dict(zip(archive.cells.tolist(), archive.objective.tolist()))
    image = matplotlib.image.imread(png)  # floats in [0, 1], height x width x 3 or 4
    height, width = image.shape[:2]
    pixels = (image[:, :, :3] * 255 + 0.5).astype(int)
    colours = {tuple(p) for p in pixels.reshape(-1, 3)[:: max(1, height * width // 20000)]}
    if len(colours) < 5:
        failures.append(f"{png}: only {len(colours)} colours, not a drawn figure")
    if dump["shape"] != grid.shape or dump["elites"] != len(filled) or dump.get("filled") != len(filled):
        failures.append(f"{png}: dump says shape {dump['shape']}, {dump['elites']} elites; the run: {grid.shape}, "
                        f"{len(filled)}")
    fitness = dump["color"] == "fitness"
    if fitness:
        cmap = matplotlib.colormaps[dump["cmap"]]
        norm = matplotlib.colors.Normalize(dump["vmin"], dump["vmax"])
    axes = {a["panel"]: a for a in dump["axes"]}
    every = np.arange(grid.cells)
    bins = grid.unravel(every)
    cols = maps.position(bins, grid.shape, layout["horizontal"])
    rows = maps.position(bins, grid.shape, layout["vertical"]) if layout["vertical"] else np.zeros_like(every)
    panels = bins[0] if layout["layout"] == "panels" else [None] * grid.cells
    wrong = unclear = 0
    for cell in range(grid.cells):
        panel, row, col = (None if panels[cell] is None else int(panels[cell])), int(rows[cell]), int(cols[cell])
        a = axes.get(panel)
        if a is None:
            failures.append(f"{png}: no image for panel {panel}")
            break
        x0, y0, x1, y1 = a["bbox"]
        x = x0 + (col + 0.5) / a["cols"] * (x1 - x0)
        y = y0 + (row + 0.5) / a["rows"] * (y1 - y0)
        px, py = int(x), int(height - y)  # PNG rows run from the top
        got = tuple(pixels[py, px])
        if cell in filled:
            want = tuple(int(c * 255 + 0.5) for c in cmap(norm(filled[cell]))[:3]) if fitness else BLUE
        else:
            want = WHITE
        if near(got, want):
            continue
        grey = max(got) - min(got) <= 12
        # Another cell state: white for an elite, a colour of the map for an empty cell. Anything else
        # is a frame or separator line drawn over a small cell's centre.
        if (cell in filled and near(got, WHITE)) or (cell not in filled and not grey) and \
                (fitness or near(got, BLUE)):
            wrong += 1
            if wrong <= 5:
                failures.append(f"{png}: cell {cell} (panel {panel}, row {row}, column {col}) at pixel ({px}, {py}) "
                                f"is {got}, expected {want} ({'elite' if cell in filled else 'empty'})")
        else:  # a frame or separator line drawn over a small cell's centre
            unclear += 1
    if wrong > 5:
        failures.append(f"{png}: {wrong} cells wrong in all")
    if unclear > 0.05 * grid.cells:
        failures.append(f"{png}: {unclear} of {grid.cells} cell centres are neither white nor the elite colour")
    return failures


def main():
    pngs = [Path(p) for p in sys.argv[1:]]
    if not pngs:
        sys.exit("map_check.py: no maps given")
    failures = []
    for png in pngs:
        failures += check(png)
    if failures:
        print("map check FAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print("map check ok: " + ", ".join(p.name for p in pngs))


if __name__ == "__main__":
    main()
