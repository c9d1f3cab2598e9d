"""What the end-to-end tests check of any figure qdplot writes (imported by qdplot_check.py,
map_check.py and the shell tests): a real PNG of the documented size that matplotlib drew, an SVG
of the same size, and a figure that explains itself (the `figure` block of qdplot --dump-data:
labelled axes with labelled ticks, and a legend or colour bar). Run directories are read with the
tools' own reader (share/qdtools)."""
import math
import struct
import sys
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "share"))
sys.dont_write_bytecode = True

from qdtools import runs  # noqa: E402  (the reader, for the checks that import this module)

__all__ = ["runs", "png_size", "svg_size", "drawn", "explained"]


def png_size(path):
    """(width, height) of a PNG whose image data decodes to the size its header states."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat = 8, b""
    width = height = depth = colour = None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[colour]
    raw = zlib.decompress(idat)  # one filter byte + one row per line
    if len(raw) != height * (1 + math.ceil(width * channels * depth / 8)):
        raise ValueError(f"{path}: image data of the wrong length")
    return width, height


def svg_size(path):
    root = ET.parse(path).getroot()
    if not root.tag.endswith("svg"):
        raise ValueError(f"{path}: root element {root.tag}")
    return float(root.get("width").rstrip("pt")), float(root.get("height").rstrip("pt"))


def drawn(path, min_colours=20, min_drawn=0.02):
    """Whether a PNG is a drawn figure: enough colours, and enough of it not white."""
    import matplotlib.image
    pixels = (matplotlib.image.imread(path)[:, :, :3] * 255).astype(int).reshape(-1, 3)
    colours = {tuple(p) for p in pixels[:: max(1, len(pixels) // 50000)]}
    share = sum(1 for p in pixels[:: max(1, len(pixels) // 50000)] if tuple(p) != (255, 255, 255)) / \
        len(pixels[:: max(1, len(pixels) // 50000)])
    return len(colours) > min_colours and share > min_drawn, f"{len(colours)} colours, {share:.1%} drawn"


def explained(dump, stem):
    """Failures of a figure's `figure` block: a legend or colour bar; a labelled horizontal and a
    labelled vertical axis; at least two labelled ticks on every labelled axis (panels label their
    outer axes only)."""
    fig = dump.get("figure")
    if fig is None:
        return [f"{stem}: no 'figure' block in its dump"]
    out = []
    if not fig["legends"] and not fig["colorbars"]:
        out.append(f"{stem}: no legend and no colour bar")
    for side in ("x", "y"):
        labelled = [a for a in fig["axes"] if a[f"{side}label"]]
        if not labelled:
            out.append(f"{stem}: no {side} axis is labelled")
        for a in labelled:
            if a[f"{side}ticks"] < 2:
                out.append(f"{stem}: {side} axis {a[side + 'label']!r} has {a[side + 'ticks']} labelled ticks")
    return out
