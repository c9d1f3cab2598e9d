#!/usr/bin/python3
"""Checks the paper's experiment files (experiments/<variant>/<algorithm>.toml) against the paper.

The expected values are written here independently of the files: the budgets of the paper's figures
(Striker 10^6 evaluations after loop 0, Walker and Kicker 2 x 10^6), the paper's table of PoMS
hyperparameters (HD / LD / sigma per environment, mix-scale included), the observation variants of
the paper's text, the reference code's seeds (one per config) and the algorithm of every file. Every directory
of experiments/ except smoke/, reference/ (reference_table.py) and the CMA-ME benchmark's lp-sphere/ and
lp-rastrigin/ must be one of the six variants, with the eight algorithm files.

  paper_table.py EXPERIMENTS_DIR     check the files; exit 1 listing every mismatch
  paper_table.py --self-test DIR     check that a copy of DIR with one wrong value fails, per value
"""
import sys
import tomllib
from pathlib import Path

import mutations

# Variant -> environment type, [environment] keys, evaluations after loop 0, PoMS (HD, LD, sigma).
VARIANTS = {
    "striker": ("striker", {"mix_scale": False}, 1_000_000, (100, 50, 0.1)),
    "striker-mix-scale": ("striker", {"mix_scale": True, "mix_scale_elements": "paper"}, 1_000_000, (100, 20, 0.01)),
    "bipedal-walker": ("bipedal-walker", {"mix_scale": False}, 2_000_000, (100, 50, 0.1)),
    "bipedal-walker-mix-scale": ("bipedal-walker", {"mix_scale": True, "mix_scale_elements": "paper"}, 2_000_000,
                                 (100, 100, 0.1)),
    "bipedal-kicker": ("bipedal-kicker", {"mix_scale": False, "normalised": True}, 2_000_000, (100, 100, 0.01)),
    "bipedal-kicker-mix-scale": ("bipedal-kicker", {"mix_scale": True, "mix_scale_elements": "paper"}, 2_000_000,
                                 (100, 50, 0.01)),
}
INITIAL_SAMPLES = 2000  # loop 0 of every file (the reference's Walker MAP-Elites configs: 200, see README)
# Seeds of the reference code's configs: algorithm -> (striker, walker, kicker); mix-scale as plain.
SEEDS = {"poms": (500, 100, 200), "poms-no-jacobian": (300, 100, 300), "poms-pca": (400, 500, 500),
         "dde": (400, 500, 200), "iso": (300, 200, 500), "iso-line-dd": (400, 400, 400),
         "ps-uniform": (100, 400, 400), "ps-glorot": (300, 200, 100)}
ENV_INDEX = {"striker": 0, "bipedal-walker": 1, "bipedal-kicker": 2}
# Directories of experiments/ that are not the paper's text: the smoke runs, the reference set
# (reference_table.py) and the CMA-ME benchmark.
NOT_PAPER_DIRS = {"smoke", "reference", "lp-sphere", "lp-rastrigin"}


def load(path, depth=0):
    """The file with its includes merged in, as qdrun does: tables merge key by key, the including
    file wins."""
    with open(path, "rb") as f:
        table = tomllib.load(f)
    includes = table.pop("include", [])
    merged = {}
    for rel in [includes] if isinstance(includes, str) else includes:
        merge(merged, load(path.parent / rel, depth + 1))
    merge(merged, table)
    return merged


def merge(base, over):
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            merge(base[k], v)
        else:
            base[k] = v


def expected_algorithm(alg, hd, ld, sigma):
    """(representation, mutator, initial) keys each algorithm file must hold."""
    ae = {"type": "autoencoder", "hidden": hd, "latent": ld}
    return {"poms": (ae, {"type": "poms", "sigma": sigma}, "uniform"),
            "poms-pca": ({"type": "pca", "latent": ld}, {"type": "poms", "sigma": sigma}, "uniform"),
            "poms-no-jacobian": (ae, {"type": "poms-no-jacobian"}, "uniform"),
            "dde": (ae, {"type": "dde"}, "uniform"),
            "iso": (None, {"type": "iso", "sigma": 0.1}, "uniform"),
            "iso-line-dd": (None, {"type": "iso-line-dd"}, "uniform"),
            "ps-uniform": (None, {"type": "uniform"}, "uniform"),
            "ps-glorot": (None, {"type": "glorot"}, "glorot")}[alg]


def check(root):
    errors = []
    root = Path(root)
    dirs = sorted(d.name for d in root.iterdir() if d.is_dir() and d.name not in NOT_PAPER_DIRS)
    for name in sorted(set(dirs) ^ set(VARIANTS)):
        errors.append(f"{name}: " + ("not a variant of the paper's table (add it here)" if name in dirs else
                                     "missing"))
    for variant in sorted(set(dirs) & set(VARIANTS)):
        env_type, env_keys, evaluations, (hd, ld, sigma) = VARIANTS[variant]
        files = sorted(p.stem for p in (root / variant).glob("*.toml") if p.name != "base.toml")
        if files != sorted(SEEDS):
            errors.append(f"{variant}: algorithm files {files}, expected {sorted(SEEDS)}")
        for alg in sorted(set(files) & set(SEEDS)):
            path = root / variant / f"{alg}.toml"
            where = f"{variant}/{alg}.toml"
            cfg = load(path)
            exp = cfg.get("experiment", {})

            def want(what, got, value):
                if got != value or type(got) is not type(value):
                    errors.append(f"{where}: {what} = {got!r}, the paper: {value!r}")

            want("experiment.name", exp.get("name"), f"{variant}-{alg}")
            want("experiment.seed", exp.get("seed"), SEEDS[alg][ENV_INDEX[env_type]])
            ps = alg.startswith("ps-")
            want("experiment.iterations", exp.get("iterations"), 1 if ps else 100)
            want("experiment.batch", exp.get("batch"), 2000 if ps else 200)
            want("experiment.initial_samples", exp.get("initial_samples"), INITIAL_SAMPLES)
            want("experiment.loops", exp.get("loops"), 1 + evaluations // (2000 if ps else 100 * 200))
            try:
                total = exp["initial_samples"] + (exp["loops"] - 1) * exp["iterations"] * exp["batch"]
                want("evaluations (loop 0 + later loops)", total, INITIAL_SAMPLES + evaluations)
            except (KeyError, TypeError):
                errors.append(f"{where}: the budget keys are incomplete")
            env = cfg.get("environment", {})
            want("environment.type", env.get("type"), env_type)
            for key, value in env_keys.items():
                want(f"environment.{key}", env.get(key), value)
            for key in sorted(set(env) - set(env_keys) - {"type"}):
                errors.append(f"{where}: environment.{key} is set, but the paper's variant does not say it")
            want("policy.hidden", cfg.get("policy", {}).get("hidden"), [32, 32])
            rep, mut, initial = expected_algorithm(alg, hd, ld, sigma)
            want("initial.type", cfg.get("initial", {}).get("type"), initial)
            if rep is None:
                if "representation" in cfg:
                    errors.append(f"{where}: has a [representation], the algorithm has none")
            else:
                for key, value in rep.items():
                    want(f"representation.{key}", cfg.get("representation", {}).get(key), value)
            for key, value in mut.items():
                want(f"mutator.{key}", cfg.get("mutator", {}).get(key), value)
    return errors


# One wrong value per row: (file, text in it, replacement). Each must make check() fail naming the file.
MUTATIONS = [
    ("bipedal-walker/base.toml", "loops = 101", "loops = 51"),
    ("bipedal-kicker/ps-uniform.toml", "loops = 1001", "loops = 501"),
    ("striker/base.toml", "loops = 51", "loops = 101"),
    ("bipedal-walker/base.toml", "initial_samples = 2000", "initial_samples = 200"),
    ("striker-mix-scale/poms.toml", "latent = 20", "latent = 50"),
    ("striker-mix-scale/poms-pca.toml", "sigma = 0.01", "sigma = 0.1"),
    ("bipedal-walker-mix-scale/dde.toml", "latent = 100", "latent = 50"),
    ("bipedal-kicker-mix-scale/poms-no-jacobian.toml", "latent = 50", "latent = 100"),
    ("bipedal-kicker/poms.toml", "hidden = 100", "hidden = 50"),
    ("striker-mix-scale/base.toml", 'mix_scale_elements = "paper"', 'mix_scale_elements = "companion"'),
    ("bipedal-kicker/base.toml", "normalised = true", "normalised = false"),
    ("bipedal-walker/iso.toml", "seed = 200", "seed = 201"),
]


def self_test(root):
    # A mutation must be reported under its own variant's name.
    return mutations.self_test(root, MUTATIONS, check,
                               lambda rel, errors: any(e.startswith(rel.split("/")[0] + "/") for e in errors))


def main():
    args = sys.argv[1:]
    if len(args) == 2 and args[0] == "--self-test":
        failures = self_test(Path(args[1]))
        label = "self-test"
    elif len(args) == 1:
        failures = check(Path(args[0]))
        label = "experiment files"
    else:
        sys.exit(__doc__)
    if failures:
        print(f"{label} FAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print(f"{label} ok: {len(VARIANTS)} variants x {len(SEEDS)} algorithms match the paper")


if __name__ == "__main__":
    main()
