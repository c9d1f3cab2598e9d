"""Shared by the tools' unit tests: qdtools on the path, and run directories written by hand, so
every number a test expects is known."""
import sys
import tempfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(SOURCE / "share"))
sys.dont_write_bytecode = True  # nothing written into the source tree


def write_run(root, name="my-env-decaying", seed=1, env="point-mass", rep="none", mutator="decaying-iso",
              descriptor="point-xy", metrics=None, grid=None, archive=None, experiment_file=None, extra_env="",
              batch=10, status="complete", centroids=None, qd=None, wall=None):
    """A run directory <root>/<name>/seed-<seed>/ with config.toml, provenance.toml, metrics.csv (the
    columns qdrun writes; the QD metrics empty unless `qd` is given) and, when given, grid.toml and
    archive.csv. `metrics`: rows (loop, evaluations, elites[, mixing_ratio]); `grid`: (shape, names,
    lower, upper[, labels]); `centroids`: (names, rows of coordinates[, lower, upper]), a CVT's
    grid.toml (bounds: the given, else the centroids' own) and centroids.csv instead; `archive`:
    rows (index, objective, measures...); `qd`: per metrics row (qd_score, max_fitness,
    mean_fitness), a task with fitness; `wall`: each metrics row's wall seconds (default 0.1 per row)."""
    d = Path(root) / name / f"seed-{seed}"
    d.mkdir(parents=True)
    (d / "config.toml").write_text(
        f'[experiment]\nname = "{name}"\nseed = {seed}\nloops = 3\nbatch = {batch}\n'
        f'[environment]\ntype = "{env}"\n{extra_env}\n[descriptor]\ntype = "{descriptor}"\n'
        f'[representation]\ntype = "{rep}"\n[mutator]\ntype = "{mutator}"\n')
    prov = f'seed = {seed}\nworkers = 1\ngit_revision = "abc"\ncpu = "CPU"\ninstruction_set = "-march=x"\n'
    if experiment_file:
        prov += f'experiment_file = "{experiment_file}"\n'
    (d / "provenance.toml").write_text(prov)
    rows = metrics or [(0, 20, 5), (1, 30, 8), (1, 40, 9), (2, 50, 12)]
    cells = 100
    if grid:
        shape, names, lower, upper = grid[:4]
        cells = 1
        for n in shape:
            cells *= n
        text = f"cells = {cells}\nshape = {list(shape)}\nnames = {list(names)}\nlower = {list(lower)}\nupper = {list(upper)}\n"
        if len(grid) > 4:
            text += f"labels = {grid[4]}\n"
        (d / "grid.toml").write_text(text.replace("'", '"'))
    if centroids:
        names, points = centroids[:2]
        cells = len(points)
        lower = list(centroids[2]) if len(centroids) > 2 else [min(p[k] for p in points) for k in range(len(names))]
        upper = list(centroids[3]) if len(centroids) > 3 else [max(p[k] for p in points) for k in range(len(names))]
        (d / "grid.toml").write_text((f'kind = "cvt"\ncells = {cells}\nshape = [{cells}]\nnames = {list(names)}\n'
                                      f'lower = {lower}\nupper = {upper}\ncentroids = "centroids.csv"\n'
                                      'centroids_crc32c = "00000000"\n').replace("'", '"'))
        (d / "centroids.csv").write_text(",".join(["centroid"] + list(names)) + "\n" + "".join(
            ",".join(map(str, [c] + list(p))) + "\n" for c, p in enumerate(points)))
    lines = ["loop,iteration,evaluations,elites,coverage,qd_score,max_fitness,mean_fitness,mixing_ratio,added,replaced,"
             "invalid,wall_seconds,train_seconds"]
    iteration = {}
    for i, r in enumerate(rows):
        loop, ev, el = r[:3]
        ratio = r[3] if len(r) > 3 else ""
        q = ",".join(map(str, qd[i])) if qd else ",,"
        it = iteration[loop] = iteration.get(loop, -1) + 1  # the iteration within its loop, as qdrun counts
        lines.append(f"{loop},{it},{ev},{el},{el / cells},{q},{ratio},0,0,0,{wall[i] if wall else 0.1 * (i + 1)},0")
    (d / "metrics.csv").write_text("\n".join(lines) + "\n")
    if archive is not None:
        dims = len(archive[0]) - 2 if archive else 2
        header = ["index", "objective"] + [f"measures_{k}" for k in range(dims)] + ["recn_error", "solution_0",
                                                                                   "solution_1"]
        body = [",".join(map(str, list(a) + [0, 0.5, -0.5])) for a in archive]
        (d / "archive.csv").write_text(",".join(header) + "\n" + "".join(b + "\n" for b in body))
    (d / "status").write_text(status + "\n")
    return d


def tmpdir(test):
    """A temporary directory removed after the test."""
    t = tempfile.TemporaryDirectory(prefix="qdtools-test-")
    test.addCleanup(t.cleanup)
    return Path(t.name)
