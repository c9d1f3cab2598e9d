"""Run directories: finding them and reading what qdrun wrote (docs/user-guide.md, "Run
directories"). Every reader takes a file plain or gzip-compressed (NAME or NAME.gz), as studies in
results/ keep their larger files compressed."""
import gzip
import io
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from . import ToolError, tables


def locate(path):
    """PATH, or PATH.gz when only the compressed file exists; None when neither does."""
    path = Path(path)
    if path.exists():
        return path
    gz = path.with_name(path.name + ".gz")
    return gz if gz.exists() else None


def open_text(path):
    """A text stream of PATH or PATH.gz (FileNotFoundError naming PATH when neither exists)."""
    found = locate(path)
    if found is None:
        raise FileNotFoundError(2, "No such file or directory", str(path))
    if found.suffix == ".gz":
        return io.TextIOWrapper(gzip.open(found, "rb"), encoding="utf-8")
    return open(found, encoding="utf-8")


def read_toml(path):
    found = locate(path)
    if found is None:
        raise FileNotFoundError(2, "No such file or directory", str(path))
    try:
        with open_text(found) as f:
            return tomllib.loads(f.read())
    except tomllib.TOMLDecodeError as e:
        raise ToolError(f"{found}: {e}") from e


def number(text):
    """A CSV field: a float (NaN when empty), or the text itself when it is not a number."""
    if text == "":
        return math.nan
    try:
        return float(text)
    except ValueError:
        return text


def read_csv(path, columns=None, text=False):
    """Rows of a qdrun CSV file as dicts of numbers (number()), or of the fields' text (`text`).
    `columns`: read only the leading columns up to the last one named (archive.csv's thousands of
    parameter columns are skipped). The last column keeps any commas of its field."""
    rows = []
    with open_text(path) as f:
        header = f.readline().rstrip("\n").split(",")
        keep = len(header)
        if columns is not None:
            missing = [c for c in columns if c not in header]
            if missing:
                raise ToolError(f"{path}: no column {', '.join(missing)} (header: {','.join(header[:8])}...)")
            keep = max(header.index(c) for c in columns) + 1
        names = header[:keep]
        for line in f:
            if not line.strip():
                continue
            values = line.rstrip("\n").split(",", keep - 1 if columns is None else keep)[:keep]
            rows.append({k: v if text else number(v) for k, v in zip(names, values)})
    return rows


def csv_header(path):
    with open_text(path) as f:
        return f.readline().rstrip("\n").split(",")


@dataclass
class Grid:
    """grid.toml: the descriptor's grid. A cell index is row-major over `shape`, the last dimension
    fastest. `labels[d]` names the bins of dimension d (empty when the descriptor names none).
    kind "cvt": a centroidal Voronoi tessellation, shape = [cells], `names`, `lower` and `upper` per
    descriptor dimension, and a cell is the index of its centroid (`centroids`, from centroids.csv)."""
    cells: int
    shape: list
    names: list
    lower: list
    upper: list
    labels: list = field(default_factory=list)
    kind: str = "grid"
    centroids: object = None  # numpy array, cells x dimensions (kind "cvt")

    @property
    def is_cvt(self):
        return self.kind == "cvt"

    @property
    def dimensions(self):
        return len(self.names)

    def unravel(self, cells):
        """Per dimension, the bin of every cell index (a grid's, not a CVT's)."""
        import numpy as np
        assert not self.is_cvt, "a CVT's cells are centroids, not bins"
        out, rest = [], np.asarray(cells, dtype=np.int64)
        for bins in reversed(self.shape):
            out.append(rest % bins)
            rest = rest // bins
        return out[::-1]

    def bin_label(self, d, k):
        return self.labels[d][k] if d < len(self.labels) and self.labels[d] else str(k)

    def describe_dimension(self, d):
        return f"{self.shape[d]} bins over [{self.lower[d]:g}, {self.upper[d]:g}]"


def read_grid(run_dir):
    """A run directory's grid.toml (with a CVT's centroids); None for runs made before qdrun wrote it."""
    path = Path(run_dir) / "grid.toml"
    try:
        g = read_toml(path)
    except FileNotFoundError:
        return None
    kind = g.get("kind", "grid")
    if kind not in ("grid", "cvt"):
        raise ToolError(f"{path}: kind = \"{kind}\" is neither \"grid\" nor \"cvt\" (a newer qdrun's run?)")
    shape = [int(b) for b in g["shape"]]
    names = list(g["names"])
    labels = [list(x) for x in g.get("labels", [])]
    dims = len(names) if kind == "cvt" else len(shape)
    if math.prod(shape) != g["cells"] or (kind == "cvt" and len(shape) != 1) or len(names) != dims or \
            len(g["lower"]) != dims or len(g["upper"]) != dims or (labels and (
                kind == "cvt" or len(labels) != len(shape) or any(x and len(x) != n for x, n in zip(labels, shape)))):
        raise ToolError(f"{path}: shape {shape} does not match cells = {g['cells']}, names, bounds or labels")
    centroids = read_centroids(path, g, names) if kind == "cvt" else None
    return Grid(int(g["cells"]), shape, names, [float(v) for v in g["lower"]], [float(v) for v in g["upper"]],
                labels, kind, centroids)


def read_centroids(grid_path, g, names):
    """A CVT's centroids (centroids.csv or .gz beside grid.toml: `centroid,<name>...`, one row per
    cell in order) as a cells x dimensions array; None for a study's copy of a run that keeps
    neither the archive nor the centroids (share/qdresults --archives maps)."""
    import numpy as np
    path = grid_path.parent / g.get("centroids", "centroids.csv")
    try:
        header = csv_header(path)
        rows = read_csv(path)
    except FileNotFoundError as e:
        if locate(grid_path.parent / "archive.csv") is None:
            return None
        raise ToolError(f"{grid_path}: a CVT grid whose centroids ({path.name}) are missing") from e
    if header != ["centroid"] + names or [r["centroid"] for r in rows] != list(range(g["cells"])):
        raise ToolError(f"{path}: not the {g['cells']} centroids of grid.toml's {', '.join(names)} "
                        f"(header: {','.join(header)}; {len(rows)} rows)")
    return np.array([[r[n] for n in names] for r in rows], dtype=float).reshape(len(rows), len(names))


@dataclass
class Archive:
    """The final archive without its parameters: cell index, objective (fitness) and descriptor
    values per elite (archive.csv, or a study's parameter-free archive.csv.gz)."""
    cells: object       # numpy int64 array
    objective: object   # numpy float array
    measures: object    # numpy array, elites x dimensions


def read_archive(run_dir):
    """The run's archive.csv (or .gz) without the solution_* columns; None when there is none."""
    import numpy as np
    path = Path(run_dir) / "archive.csv"
    if locate(path) is None:
        return None
    header = csv_header(path)
    measures = [c for c in header if c.startswith("measures_")]
    rows = read_csv(path, columns=["index", "objective"] + measures)
    cells = np.array([int(r["index"]) for r in rows], dtype=np.int64)
    objective = np.array([r["objective"] for r in rows], dtype=float)
    values = np.array([[r[c] for c in measures] for r in rows], dtype=float).reshape(len(rows), len(measures))
    return Archive(cells, objective, values)


def session_provenance(run_dir):
    """The provenance files of a run's resumed sessions (provenance-resume-loop-L.toml), by L."""
    found = [(int(m.group(1)), p) for p in Path(run_dir).glob("provenance-resume-loop-*.toml")
             if (m := re.fullmatch(r"provenance-resume-loop-(\d+)\.toml", p.name))]
    return [p for _, p in sorted(found)]


class Run:
    """One run directory, read lazily where reading is expensive (metrics are read at once: every
    figure and table needs them)."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            self.config = read_toml(self.path / "config.toml")
        except FileNotFoundError as e:
            raise ToolError(f"{self.path}: not a run directory (no config.toml)") from e
        try:
            self.provenance = read_toml(self.path / "provenance.toml")
        except FileNotFoundError:
            self.provenance = {}
        # Each session's provenance: another revision or CPU may have made the later loops.
        self.sessions = ([self.provenance] if self.provenance else []) + \
            [read_toml(p) for p in session_provenance(self.path)]
        algs, envs = tables.algorithms(), tables.environments()
        env = self.config["environment"]
        self.env_type = env["type"]
        self.env = envs.variant(env)
        self.descriptor_type = self.config.get("descriptor", {}).get("type")
        self.representation = self.config.get("representation", {}).get("type", "none")
        self.mutator = self.config["mutator"]["type"]
        self.grid = read_grid(self.path)
        self.algorithm = algs.name_of(self.representation, self.mutator) or self._label_from_file()
        if self.grid and self.grid.is_cvt and self.algorithm == algs.name_of(self.representation, self.mutator):
            self.algorithm += tables.CVT_SUFFIX  # the same pair on a CVT archive is another curve than on a grid
        self.experiment = (algs.by_pair.get((self.representation, self.mutator)) or {}).get("experiment")
        epochs = self.config.get("representation", {}).get("max_epochs") if self.representation == "autoencoder" \
            else None
        self.epoch_cap = epochs if epochs is not None and epochs != algs.paper_epochs else None
        self.index_space, self.index_space_label = algs.index_space(self.config)
        self.seed = self.config["experiment"]["seed"]
        self.batch = self.config["experiment"]["batch"]
        self.loops = self.config["experiment"]["loops"]
        try:
            self.metrics = read_csv(self.path / "metrics.csv")
        except FileNotFoundError as e:
            raise ToolError(f"{self.path}: no metrics.csv (a run that never finished loop 0?)") from e
        self.cells = self.grid.cells if self.grid else self.provenance.get("cells")
        if self.cells is None:  # coverage = elites / cells
            last = self.metrics[-1] if self.metrics else {}
            self.cells = round(last["elites"] / last["coverage"]) if last.get("coverage") else 1
        status = locate(self.path / "status")
        self.status = status.read_text().strip() if status else ""

    def _label_from_file(self):
        """An algorithm the table does not know is named after its experiment file (its stem), else
        after its experiment, else by its (representation/mutator) pair."""
        path = self.provenance.get("experiment_file")
        if path:
            return Path(path).stem
        return self.config["experiment"].get("name") or f"{self.representation}/{self.mutator}"

    def has_fitness(self):
        """Whether the run's task has a fitness: its QD metrics (metrics.csv's qd_score) are numbers."""
        return any(isinstance(m.get("qd_score"), float) and not math.isnan(m["qd_score"]) for m in self.metrics)

    @property
    def complete(self):
        return self.status == "complete"

    def final_elites(self):
        return int(self.metrics[-1]["elites"]) if self.metrics else 0

    def last(self, key, default=math.nan):
        v = self.metrics[-1].get(key, default) if self.metrics else default
        return default if isinstance(v, float) and math.isnan(v) else v

    def coverage_text(self, elites):
        """'N elites (x % of C cells)', with the % of a second index space (the Walker's) too."""
        text = f"{elites} elites ({100 * elites / self.cells:.2f} % of {self.cells}"
        if self.index_space:
            text += f"; {100 * elites / self.index_space:.2f} % of {self.index_space}"
        return text + ")"

    def archive(self):
        return read_archive(self.path)

    def file(self, name):
        """The run's NAME or NAME.gz, or None."""
        return locate(self.path / name)

    def __repr__(self):
        return f"Run({self.path})"


def is_run_dir(path):
    path = Path(path)
    return (path / "config.toml").exists() and locate(path / "metrics.csv") is not None


def find_runs(paths):
    """Run directories, or roots holding <name>/seed-<seed>/ runs (searched recursively), in order,
    each once."""
    found = []
    for p in map(Path, paths):
        if (p / "config.toml").exists():
            found.append(p)
            continue
        if not p.is_dir():
            raise ToolError(f"{p}: not a run directory or a directory of runs")
        runs = sorted(d.parent for d in p.rglob("config.toml") if is_run_dir(d.parent))
        if not runs:
            raise ToolError(f"{p}: holds no run directories (<name>/seed-<seed>/config.toml)")
        found.extend(runs)
    return [Run(p) for p in dict.fromkeys(found)]


def median_run(runs):
    """The run of median final coverage (the lower median for an even count): a group's example."""
    ranked = sorted(runs, key=lambda r: (r.final_elites(), r.seed))
    return ranked[(len(ranked) - 1) // 2]


def group(runs):
    """{environment: {algorithm: [runs]}} of the runs that have metrics rows."""
    groups = {}
    for r in runs:
        if r.metrics:
            groups.setdefault(r.env, {}).setdefault(r.algorithm, []).append(r)
    return groups
