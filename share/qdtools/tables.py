"""The tables of share/, read once: algorithms.toml (the paper's algorithms, their colours and the
paper's constants) and environments.toml (variant names, trajectory columns, map orientation).

Nothing else in the tools spells an algorithm or environment name: a new algorithm or environment
variant is an entry in these files (tests/docs/check_docs.py checks the README against them)."""
import functools
import tomllib
from pathlib import Path

from . import ToolError

SHARE = Path(__file__).resolve().parent.parent  # share/ in the source tree, <prefix>/share/qd installed


def load(name, share=SHARE):
    path = Path(share) / name
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as e:
        raise ToolError(f"cannot read {path}: {e.strerror} (it is installed beside the qdtools package)") from e
    except tomllib.TOMLDecodeError as e:
        raise ToolError(f"{path}: {e}") from e


# An algorithm of the table run on a CVT archive is labelled with this suffix (runs.Run.algorithm).
CVT_SUFFIX = " CVT"
# Colours and markers of algorithms the table does not know (none of the table's).
OTHER_STYLES = [("black", "."), ("tab:pink", "P"), ("tab:gray", "*"), ("tab:olive", "X"), ("tab:cyan", "h")]


class Algorithms:
    """share/algorithms.toml: one entry per algorithm of the paper, in legend order."""

    def __init__(self, table):
        self.entries = table["algorithm"]
        self.paper_epochs = table["paper"]["autoencoder_epochs"]
        self.index_spaces = table["paper"].get("index_space", [])
        self.by_pair = {(a["representation"], a["mutator"]): a for a in self.entries}
        self.by_experiment = {a["experiment"]: a for a in self.entries}
        self.by_name = {a["name"]: a for a in self.entries}
        self.order = [a["name"] for a in self.entries]
        self.experiments = [a["experiment"] for a in self.entries]

    def name_of(self, representation, mutator):
        a = self.by_pair.get((representation, mutator))
        return a["name"] if a else None

    def styles(self, names):
        """{name: (colour, marker, linestyle)} for the curves of one figure: the table's for its
        algorithms; a table algorithm on a CVT archive (name + CVT_SUFFIX) its colour and marker,
        dashed; other names, in legend order, a colour and marker of their own (OTHER_STYLES, then
        repeated with dotted lines), so no two curves of a figure look alike."""
        out, others = {}, []
        for name in sorted(set(names), key=self.rank):
            base = self.by_name.get(name.removesuffix(CVT_SUFFIX))
            if name in self.by_name:
                out[name] = (base["colour"], base["marker"], "-")
            elif base and name.endswith(CVT_SUFFIX):
                out[name] = (base["colour"], base["marker"], "--")
            else:
                others.append(name)
        for k, name in enumerate(others):
            colour, marker = OTHER_STYLES[k % len(OTHER_STYLES)]
            out[name] = (colour, marker, ("-", ":", "-.")[k // len(OTHER_STYLES) % 3])
        return out

    def rank(self, name):
        """Legend order: the table's (each algorithm followed by its CVT run), then unknown names
        alphabetically."""
        base = name.removesuffix(CVT_SUFFIX)
        return (self.order.index(base) if base in self.order else len(self.order), name)

    def plots_mixing_ratio(self, name):
        return bool(self.by_name.get(name.removesuffix(CVT_SUFFIX), {}).get("mixing_ratio"))

    def is_sampler(self, experiment):
        """Random search draws fresh policies every loop (its mutator is its loop-0 sampler)."""
        a = self.by_experiment.get(experiment)
        return bool(a) and a["mutator"] == a["initial"]

    def index_space(self, config):
        """The reference's own index space for a run's descriptor (a second coverage denominator,
        [[paper.index_space]]): (cells, label), or (None, None)."""
        desc = config.get("descriptor", {})
        for entry in self.index_spaces:
            if desc.get("type") == entry["descriptor"] and all(desc.get(k, v) == v for k, v in entry["when"].items()):
                return entry["cells"], entry["label"]
        return None, None


class Environments:
    """share/environments.toml: variant names, what trace columns are, how grids are oriented."""

    def __init__(self, table):
        self.suffixes = table.get("suffix", [])
        self.by_type = {e["type"]: e for e in table.get("environment", [])}
        self.descriptors = {d["type"]: d for d in table.get("descriptor", [])}
        self.paper_figures = {f["variant"]: f for f in table.get("paper_figure", [])}

    def variant(self, env):
        """The name of a run's environment ([environment] table of config.toml) as the directories
        of experiments/ name it: its type plus the suffixes whose conditions hold."""
        name = env["type"]
        for s in self.suffixes:
            if s.get("environment", env["type"]) != env["type"]:
                continue
            if all(env.get(k) == v for k, v in s.get("when", {}).items()) and \
                    not any(env.get(k) == v for k, v in s.get("unless", {}).items()):
                name += s["suffix"]
        return name

    def trace_style(self, env_type):
        """What the trace's main columns are for this environment type ({} for one we do not know)."""
        return self.by_type.get(env_type, {})

    def horizontal(self, descriptor_type, names):
        """The grid dimensions drawn to the right, by index, when environments.toml names them for
        this descriptor; None for the default (dimension 0 to the right)."""
        entry = self.descriptors.get(descriptor_type)
        if not entry:
            return None
        missing = [n for n in entry["horizontal"] if n not in names]
        if missing:  # a grid that changed since the table was written: fall back to the rule
            return None
        return sorted(names.index(n) for n in entry["horizontal"])


@functools.lru_cache(maxsize=None)
def algorithms(share=SHARE):
    return Algorithms(load("algorithms.toml", share))


@functools.lru_cache(maxsize=None)
def environments(share=SHARE):
    return Environments(load("environments.toml", share))


def experiment_variants(experiments_dir):
    """The environment variants of an experiment directory: its subdirectories holding a file for
    every algorithm of the table (experiments/<variant>/<experiment>.toml), the paper's comparison;
    test fixtures (smoke) and benchmarks with other algorithms (lp-sphere) left out."""
    stems = set(algorithms().experiments)
    root = Path(experiments_dir)
    return sorted(d.name for d in root.iterdir()
                  if d.is_dir() and d.name != "smoke" and stems <= {p.stem for p in d.glob("*.toml")})


@functools.lru_cache(maxsize=None)
def paper_curves(share=SHARE):
    """share/paper-curves.csv as {(figure, algorithm, quantity): (evaluations array, values array)}."""
    import csv
    import numpy as np
    path = Path(share) / "paper-curves.csv"
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        raise ToolError(f"cannot read {path}: {e.strerror} (it is installed beside the qdtools package)") from e
    curves = {}
    for r in rows:
        curves.setdefault((r["figure"], r["algorithm"], r["quantity"]), []).append((int(r["evaluations"]),
                                                                                  float(r["value"])))
    return {k: (np.array([e for e, _ in v]), np.array([x for _, x in v])) for k, v in curves.items()}


def paper_value(figure, algorithm, evaluations, quantity="coverage_percent", share=SHARE):
    """The paper's figure's value at `evaluations` (linear between its points), or None outside them."""
    import numpy as np
    curve = paper_curves(share).get((figure, algorithm, quantity))
    if curve is None or evaluations < curve[0][0] or evaluations > curve[0][-1]:
        return None
    return float(np.interp(evaluations, *curve))
