#!/usr/bin/python3
"""Checks the reference configuration set (experiments/reference/<environment>/) against the table
of experiments/README.md ("The reference configuration set").

The table is the documented copy of the reference code's configs; this script reads it (it holds no
values of its own but the algorithms' types) and checks every file: budget, loop 0, environment
and observation, policy, representation (HD, LD), mutator (Σ, σ), seed and experiment name.

  reference_table.py EXPERIMENTS_DIR             check; exit 1 listing every mismatch
  reference_table.py --self-test EXPERIMENTS_DIR   check that one wrong value in a copy fails, per value
"""
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mutations  # noqa: E402
from paper_table import load  # noqa: E402  (the includes merged as qdrun merges them)

ALGORITHMS = ["poms", "poms-pca", "poms-no-jacobian", "dde", "iso", "iso-line-dd", "ps-uniform", "ps-glorot"]
# What "observation" in the table means as [environment] keys.
OBSERVATION = {"reference": {"mix_scale": False}, "world units": {"mix_scale": False, "normalised": False}}


def tables(readme):
    """The section's two tables as lists of {header: cell} rows."""
    text = Path(readme).read_text()
    section = text.split("## The reference configuration set", 1)[1].split("\n## ", 1)[0]
    found, rows, header = [], None, None
    for line in section.splitlines() + [""]:
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if header is None:
                header, rows = cells, []
            elif not set("".join(cells)) <= set("-: "):
                rows.append(dict(zip(header, cells)))
        elif header is not None:
            found.append(rows)
            header = None
    return found


def number(text):
    return float(text) if re.search(r"[.e]", text) else int(text)


def check(root, readme):
    root, errors = Path(root), []
    found = tables(readme)
    if len(found) < 2:
        return [f"{readme}: the section 'The reference configuration set' needs its two tables"]
    settings = {r["environment"]: r for r in found[0]}
    seeds = {r["environment"]: r for r in found[1]}
    dirs = sorted(d.name for d in (root / "reference").iterdir() if d.is_dir())
    if dirs != sorted(settings) or sorted(seeds) != sorted(settings):
        errors.append(f"reference/: directories {dirs}, the tables: {sorted(settings)} and {sorted(seeds)}")
    for env in sorted(set(dirs) & set(settings) & set(seeds)):
        row, files = settings[env], sorted(p.stem for p in (root / "reference" / env).glob("*.toml"))
        if files != sorted(ALGORITHMS + ["base"]):
            errors.append(f"reference/{env}: files {files}, expected base and {ALGORITHMS}")
        hd, ld = int(row["HD"]), int(row["LD"])
        big_sigma, iso_sigma = number(row["Σ (PoMS, PoMS-PCA)"]), number(row["σ (MAPE-Iso)"])
        ae = {"type": "autoencoder", "hidden": hd, "latent": ld}
        expected = {"poms": (ae, {"type": "poms", "sigma": big_sigma}),
                    "poms-pca": ({"type": "pca", "latent": ld}, {"type": "poms", "sigma": big_sigma}),
                    "poms-no-jacobian": (ae, {"type": "poms-no-jacobian"}),
                    "dde": (ae, {"type": "dde"}),
                    "iso": (None, {"type": "iso", "sigma": iso_sigma}),
                    "iso-line-dd": (None, {"type": "iso-line-dd"}),
                    "ps-uniform": (None, {"type": "uniform"}),
                    "ps-glorot": (None, {"type": "glorot"})}
        for alg in sorted(set(files) & set(ALGORITHMS)):
            where = f"reference/{env}/{alg}.toml"
            cfg = load(root / "reference" / env / f"{alg}.toml")
            exp = cfg.get("experiment", {})

            def want(what, got, value):
                if got != value or type(got) is not type(value):
                    errors.append(f"{where}: {what} = {got!r}, the reference's config: {value!r}")

            ps = alg.startswith("ps-")
            want("experiment.name", exp.get("name"), f"reference-{env}-{alg}")
            want("experiment.seed", exp.get("seed"), int(seeds[env][alg]))
            want("experiment.iterations", exp.get("iterations"), 1 if ps else 100)
            want("experiment.batch", exp.get("batch"), 2000 if ps else 200)
            want("experiment.initial_samples", exp.get("initial_samples"), 2000 if ps else int(row["loop 0 (MAP-Elites)"]))
            want("experiment.loops", exp.get("loops"), int(row["loops (PS, 2000 each)" if ps else "loops (MAP-Elites)"]))
            if not ps:
                try:
                    total = exp["initial_samples"] + (exp["loops"] - 1) * exp["iterations"] * exp["batch"]
                    want("evaluations", total, int(row["evaluations (MAP-Elites)"]))
                except (KeyError, TypeError):
                    errors.append(f"{where}: the budget keys are incomplete")
            env_table = cfg.get("environment", {})
            want("environment.type", env_table.get("type"), env)
            keys = OBSERVATION.get(row["observation"])
            if keys is None:
                errors.append(f"{readme}: unknown observation '{row['observation']}' for {env}")
                keys = {}
            for key, value in keys.items():
                want(f"environment.{key}", env_table.get(key), value)
            for key in sorted(set(env_table) - set(keys) - {"type"}):
                errors.append(f"{where}: environment.{key} is set, the reference's config does not say it")
            want("policy.hidden", cfg.get("policy", {}).get("hidden"), [32, 32])
            want("initial.type", cfg.get("initial", {}).get("type"), "glorot" if alg == "ps-glorot" else "uniform")
            rep, mut = expected[alg]
            if rep is None:
                if "representation" in cfg:
                    errors.append(f"{where}: has a [representation], the algorithm has none")
            else:
                for key, value in rep.items():
                    want(f"representation.{key}", cfg.get("representation", {}).get(key), value)
            for key, value in mut.items():
                want(f"mutator.{key}", cfg.get("mutator", {}).get(key), value)
            for table, allowed in (("representation", rep or {}), ("mutator", mut)):
                for key in sorted(set(cfg.get(table, {})) - set(allowed)):
                    errors.append(f"{where}: {table}.{key} is set, the reference's config does not say it")
    return errors


# One wrong value per row (file under experiments/, text in it, replacement). Each must fail naming the file.
MUTATIONS = [
    ("reference/bipedal-walker/base.toml", "initial_samples = 200", "initial_samples = 2000"),
    ("reference/bipedal-walker/base.toml", "loops = 51", "loops = 101"),
    ("reference/bipedal-kicker/base.toml", "normalised = false", "normalised = true"),
    ("reference/bipedal-kicker/poms.toml", "latent = 100", "latent = 50"),
    ("reference/bipedal-kicker/poms-pca.toml", "sigma = 0.01", "sigma = 0.1"),
    ("reference/bipedal-kicker/iso.toml", "sigma = 0.1", "sigma = 0.01"),
    ("reference/striker/dde.toml", "hidden = 100", "hidden = 50"),
    ("reference/striker/ps-uniform.toml", "loops = 501", "loops = 1001"),
    ("reference/bipedal-walker/poms-pca.toml", "seed = 500", "seed = 100"),
    ("reference/striker/ps-glorot.toml", 'type = "glorot"', 'type = "uniform"'),
    # The README's table is checked too: a changed value there fails against the files.
    ("README.md", "| bipedal-walker | 200 | 51 |", "| bipedal-walker | 2000 | 51 |"),
    ("README.md", "| bipedal-kicker | 200 | 500 | 300 |", "| bipedal-kicker | 200 | 500 | 301 |"),
]


def self_test(root):
    return mutations.self_test(root, MUTATIONS, lambda d: check(d, d / "README.md"))


def main():
    args = sys.argv[1:]
    if len(args) == 2 and args[0] == "--self-test":
        failures, label = self_test(Path(args[1])), "self-test"
    elif len(args) == 1:
        failures, label = check(Path(args[0]), Path(args[0]) / "README.md"), "reference set"
    else:
        sys.exit(__doc__)
    if failures:
        print(f"{label} FAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print(f"{label} ok: {len(ALGORITHMS)} algorithms x 3 environments match experiments/README.md")


if __name__ == "__main__":
    main()
