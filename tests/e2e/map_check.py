#!/usr/bin/python3
"""Checks qdplot's archive maps pixel by pixel against the run directory alone.

  map_check.py MAP.png [MAP.png ...]

Each MAP.png needs the MAP.json that qdplot --dump-data writes beside it: the run directory it
draws and where each image lies in the figure. The expected picture is computed here from the run's archive.csv and grid.toml with
the layout documented in share/README.md, independently of qdplot: the cell index is row-major over
grid.toml's shape (the last dimension fastest); a 3-D grid with at most 36 bins in dimension 0 is one
panel per bin of dimension 0 (dimension 1 up, dimension 2 right); any other grid is one image whose
rows nest dimensions 0, 2, 4, ... and whose columns nest 1, 3, 5, ..., the earlier dimension outside
(a 1-D grid is one row). The pixel at the centre of every cell must be the elite colour (matplotlib's
tab:blue) when the archive holds the cell and white when it does not (a centre under a panel frame
or separator line is skipped; at most 5 % may be), and the PNG must be a real PNG that matplotlib
wrote (signature, and more than a few colours)."""
import json
import sys
import tomllib
from pathlib import Path

import matplotlib.image

BLUE = (0x1F, 0x77, 0xB4)
WHITE = (0xFF, 0xFF, 0xFF)


def near(colour, reference):
    """Within 40 of the reference in every channel: a faint separator line drawn across a small cell
    (light grey, partly transparent after anti-aliasing) does not change what the cell shows."""
    return max(abs(c - r) for c, r in zip(colour, reference)) <= 40


def unravel(cell, shape):
    bins = []
    for n in reversed(shape):
        bins.append(cell % n)
        cell //= n
    return bins[::-1]


def expected_positions(cell, shape):
    """(panel, row from the bottom, column from the left) of a cell."""
    bins = unravel(cell, shape)
    if len(shape) == 3 and shape[0] <= 36:
        return bins[0], bins[1], bins[2]
    if len(shape) == 1:
        return None, 0, bins[0]
    row = col = 0
    for d, b in enumerate(bins):
        if d % 2 == 0:
            row = row * shape[d] + b
        else:
            col = col * shape[d] + b
    return None, row, col


def check(png):
    failures = []
    data = png.read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return [f"{png}: not a PNG"]
    dump = json.loads(png.with_suffix(".json").read_text())
    run = Path(dump["run"])
    with open(run / "grid.toml", "rb") as f:
        grid = tomllib.load(f)
    shape = [int(n) for n in grid["shape"]]
    with open(run / "archive.csv") as f:
        f.readline()
        filled = {int(line.split(",", 1)[0]) for line in f if line.strip()}
    image = matplotlib.image.imread(png)  # floats in [0, 1], height x width x 3 or 4
    height, width = image.shape[:2]
    pixels = (image[:, :, :3] * 255 + 0.5).astype(int)
    colours = {tuple(p) for p in pixels.reshape(-1, 3)[:: max(1, height * width // 20000)]}
    if len(colours) < 5:
        failures.append(f"{png}: only {len(colours)} colours, not a drawn figure")
    axes = {a["panel"]: a for a in dump["axes"]}
    if dump["shape"] != shape or dump["elites"] != len(filled) or dump.get("filled") != len(filled):
        failures.append(f"{png}: dump says shape {dump['shape']}, {dump['elites']} elites; the run: {shape}, "
                        f"{len(filled)}")
    wrong = unclear = 0
    for cell in range(int(grid["cells"])):
        panel, row, col = expected_positions(cell, shape)
        a = axes.get(panel)
        if a is None:
            failures.append(f"{png}: no image for panel {panel}")
            break
        x0, y0, x1, y1 = a["bbox"]
        x = x0 + (col + 0.5) / a["cols"] * (x1 - x0)
        y = y0 + (row + 0.5) / a["rows"] * (y1 - y0)
        px, py = int(x), int(height - y)  # PNG rows run from the top
        got = tuple(pixels[py, px])
        seen = "elite" if near(got, BLUE) else "empty" if near(got, WHITE) else None
        if seen is None:  # a frame or separator line drawn over a small cell's centre
            unclear += 1
            continue
        want = "elite" if cell in filled else "empty"
        if seen != want:
            wrong += 1
            if wrong <= 5:
                failures.append(f"{png}: cell {cell} (panel {panel}, row {row}, column {col}) at pixel ({px}, {py}) "
                                f"is {got}: {seen}, but the archive has it {want}")
    if wrong > 5:
        failures.append(f"{png}: {wrong} cells wrong in all")
    if unclear > 0.05 * int(grid["cells"]):
        failures.append(f"{png}: {unclear} of {grid['cells']} cell centres are neither white nor the elite colour")
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
