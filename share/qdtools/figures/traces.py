"""traces-<env>-<alg>: every elite's trajectory, replayed by qdrun (--replay RUN --all --traces),
for any environment: the first two columns of its trace's `main` table (main_0 right, main_1 up), or
main_0 against the recorded row when it has one column, coloured by the path's last value of main_0.
share/environments.toml names the columns of the environments it knows and draws the Striker's
table; any other environment's columns are shown as main_0 and main_1."""
from pathlib import Path

import matplotlib
import matplotlib.cm
import matplotlib.colors
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.lines import Line2D

from .. import qdrun as qdrun_mod
from .. import tables
from ..runs import read_csv
from .common import legend_below, run_title, slug


def plot(out, run, qdrun):
    archive = run.file("archive.csv")
    if archive is None or archive.suffix == ".gz":
        print(f"qdplot: no trajectories for {run.path}: it has no archive.csv with the elites' parameters to replay")
        return
    csv = out.dir / "data" / f"traces-{slug(run.env)}-{slug(run.algorithm)}-seed-{run.seed}.csv"
    if qdrun_mod.make(qdrun, ["--replay", run.path, "--all", "--traces", csv], csv, [archive]):
        print(f"qdplot: no trajectories for {run.path}: qdrun could not replay it (above)")
        return
    rows = read_csv(csv)
    main = sorted((k for k in (rows[0] if rows else {}) if k.startswith("main_")), key=lambda k: int(k[5:]))
    if not rows or not main:
        print(f"qdplot: no trajectories for {run.path}: environment '{run.env_type}' records no rows in its trace's "
              "main table (Trace::main), which these figures draw")
        return
    style = tables.environments().trace_style(run.env_type)
    body = style.get("body", "")
    names = style.get("columns", main[:2])
    origin = style.get("origin", [0.0, 0.0])
    paths = {}
    for r in rows:
        paths.setdefault(int(r["cell"]), []).append(r)
    segments, finals = [], []
    for rs in paths.values():
        if len(main) >= 2:
            xy = [(r[main[0]] - origin[0], r[main[1]] - origin[1]) for r in rs]
        else:  # one column: its value against the recorded row
            xy = [(r["row"], r[main[0]] - origin[0]) for r in rs]
        segments.append(xy)
        finals.append(xy[-1][0] if len(main) >= 2 else xy[-1][1])
    fig = out.figure("traces")
    ax = fig.subplots(1, 1)
    # A trace of one row (a task whose outcome is a point, such as the linear-projection benchmark)
    # is drawn as a dot, a longer one as a line; one colour scale for both.
    norm = matplotlib.colors.Normalize(min(finals), max(finals))
    lines = [k for k, xy in enumerate(segments) if len(xy) > 1]
    dots = [k for k, xy in enumerate(segments) if len(xy) == 1]
    lc = LineCollection([segments[k] for k in lines], cmap="viridis", norm=norm, linewidths=0.4, alpha=0.5)
    lc.set_array(np.array([finals[k] for k in lines]))
    ax.add_collection(lc)
    colour = matplotlib.colormaps["viridis"](0.5)
    handles, labels = [], []
    if lines:
        handles.append(Line2D([], [], color=colour, linewidth=1))
        labels.append(f"one {body + ' ' if body else ''}path per elite ({len(lines)}), coloured by its final {names[0]}")
    if dots:
        xy = np.array([segments[k][0] for k in dots])
        ax.scatter(xy[:, 0], xy[:, 1], c=[finals[k] for k in dots], cmap="viridis", norm=norm, s=3, linewidths=0)
        handles.append(Line2D([], [], color=colour, marker=".", linestyle=""))
        labels.append(f"one point per elite whose trace is one row ({len(dots)}), coloured by its {names[0]}")
    ax.autoscale()
    what = (f"{body} " if body else "") + ("path" if lines else "point")
    if "outline" in style:
        xs, ys = zip(*style["outline"])
        (edge,) = ax.plot(xs, ys, color="black", linewidth=1)
        handles.append(edge)
        labels.append(style.get("outline_label", "outline"))
    if style.get("equal_aspect"):
        ax.set_aspect("equal")

    def axis_label(name, k):
        if not style:  # an environment environments.toml does not know: its trace's own column
            return f"{main[k]} (column {k + 1} of the trace's main table)"
        shift = origin[k] if k < len(origin) else 0.0
        return f"{body} {name}" + (f" - {shift:g}" if shift else "")

    if len(main) >= 2:
        ax.set_xlabel(axis_label(names[0], 0))
        ax.set_ylabel(axis_label(names[1], 1))
    else:
        ax.set_xlabel("recorded row of the trace")
        ax.set_ylabel(axis_label(names[0], 0))
    ax.grid(alpha=0.3)
    matches = sum(1 for rs in paths.values() if rs[0]["landed"] == rs[0]["cell"])
    if matches < len(paths):
        # A replay runs in a fresh world: an environment whose episodes depend on what earlier ones
        # left behind (persistent worlds, such as the Kicker's ghost balls) stored some elites in a
        # cell a fresh world does not give them. Say so on the figure, which draws the replays.
        moved = f"in a fresh world {matches} of {len(paths)} elites replay into their own cell: these are the replays' paths"
        print(f"qdplot: {run.path}: {moved}")
        handles.append(Line2D([], [], linestyle="none"))
        labels.append(moved)
    ax.set_title(run_title(run, f"{what}s of {len(paths)} elites" + ("" if style else " (the trace's main columns)")),
                 fontsize=10)
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax, shrink=0.8)
    bar.set_label(f"{'final ' if lines else ''}{body} {names[0]}".replace("  ", " ").strip())
    legend_below(fig, handles, labels, ncol=1, fontsize=8)
    fig.subplots_adjust(left=0.12, right=0.95, top=0.91, bottom=0.16)
    out.save(fig, f"traces-{slug(run.env)}-{slug(run.algorithm)}", "traces",
             {"run": str(run.path), "elites": len(paths), "rows": len(rows), "points": len(dots),
              "replayed_as_stored": matches,
              "columns": main, "source": str(Path(csv)), "epoch_cap": run.epoch_cap}, [run],
             environment=run.env, algorithm=run.algorithm)
