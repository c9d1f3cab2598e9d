"""Where figures go: PNG and SVG files of documented sizes, figures/qdplot.json (every file with its
kind, environment, algorithm, runs and size) and, with --dump-data, <figure>.json with the numbers
plotted."""
import io
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Figure sizes in inches; pixels = inches x dpi (no tight bounding box, so sizes are exact). Maps
# take theirs from their layout (figures/maps.py).
SIZES = {"coverage": (8.0, 6.0), "qd": (8.0, 9.0), "map-voronoi": (7.5, 6.5), "map-panels": (12.0, 6.5), "map-very-wide": (14.0, 4.0), "map-wide": (12.0, 4.5),
         "map-square": (7.5, 6.5), "map-tall": (6.5, 9.0), "traces": (7.0, 7.0), "latents": (11.0, 5.0),
         "losses": (8.0, 5.0)}
MANIFEST = "qdplot.json"


class Output:
    def __init__(self, directory, formats=("png", "svg"), dpi=100, dump=False, compact=False):
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.formats, self.dpi, self.dump, self.compact = list(formats), dpi, dump, compact
        self.manifest = []

    def figure(self, size_key):
        w, h = SIZES[size_key]
        return plt.figure(figsize=(w, h), dpi=self.dpi)

    def save(self, fig, stem, kind, data, runs, environment=None, algorithm=None):
        """Writes `fig` in every format and records it; `data` goes to <stem>.json with --dump-data."""
        w, h = fig.get_size_inches()
        for fmt in self.formats:
            name = f"{stem}.{fmt}"
            if fmt == "png" and self.compact:
                write_compact_png(fig, self.dir / name, self.dpi)
            else:
                fig.savefig(self.dir / name, dpi=self.dpi)
            entry = {"file": name, "kind": kind, "format": fmt, "environment": environment, "algorithm": algorithm,
                     "runs": [str(r.path) for r in runs], "seeds": sorted(r.seed for r in runs),
                     "epoch_caps": sorted({r.epoch_cap for r in runs if r.epoch_cap is not None})}
            if fmt == "png":
                entry.update(width=round(w * self.dpi), height=round(h * self.dpi))
            else:
                entry.update(width_pt=round(w * 72, 3), height_pt=round(h * 72, 3))
            self.manifest.append(entry)
            print(f"qdplot: wrote {self.dir / name}")
        if self.dump:
            data = dict(data, figure=describe(fig))
            with open(self.dir / f"{stem}.json", "w") as f:
                json.dump(data, f, indent=1, allow_nan=True)
        plt.close(fig)

    def finish(self):
        """Writes qdplot.json: this invocation's files, then those an earlier one listed that are still
        there and were not redrawn (figures that need files a study no longer keeps stay listed)."""
        written = {e["file"] for e in self.manifest}
        kept = []
        path = self.dir / MANIFEST
        if path.exists():
            try:
                earlier = json.loads(path.read_text())["files"]
            except (ValueError, KeyError):
                earlier = []
            kept = [e for e in earlier if e["file"] not in written and (self.dir / e["file"]).exists()]
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"dpi": self.dpi, "files": self.manifest + kept}, indent=1) + "\n")
        tmp.replace(path)


def describe(fig):
    """What a reader of the figure is told, as drawn: the legends' entries, the colour bars' labels,
    and per plotting axes its labels and how many of its ticks carry a label (tests check that
    every figure labels its axes and explains its colours)."""
    fig.canvas.draw()
    out = {"legends": [t.get_text() for leg in fig.legends for t in leg.get_texts()], "colorbars": [], "axes": []}
    for ax in fig.axes:
        if getattr(ax, "_colorbar", None) is not None:
            out["colorbars"].append(ax.get_ylabel() or ax.get_xlabel())
            continue
        if not ax.get_visible() or not ax.axison:
            continue
        if ax.get_legend():
            out["legends"] += [t.get_text() for t in ax.get_legend().get_texts()]

        def labelled(axis):
            return sum(1 for t in axis.get_ticklabels() if t.get_text() and t.get_visible())

        out["axes"].append({"title": ax.get_title(), "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
                            "xticks": labelled(ax.xaxis), "yticks": labelled(ax.yaxis)})
    return out


def write_compact_png(fig, path, dpi):
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    buf.seek(0)
    compact_png(buf, path)


def compact_png(source, path):
    """An 8-bit palette PNG (256 colours, no dithering) of the PNG `source` (a path or a file): a
    third of the size of matplotlib's RGBA for line art. Pillow comes with Debian's matplotlib."""
    from PIL import Image
    Image.open(source).convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                                               dither=Image.Dither.NONE).save(path, "PNG", optimize=True)


def read_manifest(directory):
    path = Path(directory) / MANIFEST
    return json.loads(path.read_text())["files"] if path.exists() else []
