"""Studies in results/: what a study keeps of its runs, and the check that a repository commits
nothing bulky (results/README.md states the rule).

A study keeps, per run, what a reader needs to check a claim: config.toml, provenance.toml (and
each resumed session's provenance-resume-loop-L.toml), grid.toml, status, training.csv (and
pca.csv), metrics.csv as metrics.csv.gz, and the final archive without its parameters as
archive.csv.gz (index, objective, measures_*, recn_error) with, for a CVT, centroids.csv as
centroids.csv.gz. Never the per-epoch losses, the parameters, checkpoints, datasets or snapshots."""
import gzip
import json
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

from .figures.output import MANIFEST, compact_png, read_manifest
from .report import study, summary
from .runs import Run, csv_header, group, is_run_dir, locate, median_run, open_text, session_provenance

KEEP = ("config.toml", "provenance.toml", "grid.toml", "status", "training.csv", "pca.csv")  # summary.toml: slim_run
COMPRESS = ("metrics.csv",)  # and centroids.csv beside a kept archive (slim_run)
# Figures a study's files cannot give again (they need parameters, checkpoints or per-epoch logs):
# copied as drawn. Coverage and maps are drawn again from the kept files (qdreport --regenerate).
KEPT_FIGURES = ("traces", "latents", "losses")

# What a run writes that no study commits: per-epoch logs, parameters, checkpoints, datasets,
# snapshots, a faulty offspring's parameters, replay data.
BULKY = [
    (re.compile(r"(^|/)losses\.csv(\.gz)?$"), "per-epoch training log"),
    (re.compile(r"\.bin(\.gz)?$"), "checkpoint, archive state or dataset"),
    (re.compile(r"(^|/)archive/loop-\d+\.csv(\.gz)?$"), "archive snapshot"),
    (re.compile(r"(^|/)fault-offspring\.csv(\.gz)?$"), "a faulty offspring's parameters"),
    (re.compile(r"(^|/)figures/data/"), "replayed trajectories or latent codes (qdplot's data/)"),
    (re.compile(r"(^|/)(lock|qdrun\.log|sweep\.log)$"), "a run's lock or log"),
]
BUDGET_RESULTS = 21 * 1000 * 1000   # bytes tracked under results/ (10 MB until the lp benchmark, 13, 15 and 18 MB in issue 36)
BUDGET_SOURCE = 4 * 1000 * 1000     # bytes tracked outside results/
LARGEST_PLAIN = 64 * 1000           # a larger text file under results/ is stored gzip-compressed


def tracked_files(root):
    """The files git tracks under root (the working tree's copies); every file outside build*/, runs/,
    out/ and .git when root is no git work tree (an unpacked archive)."""
    root = Path(root)
    try:
        out = subprocess.run(["git", "-C", str(root), "ls-files", "-z"], capture_output=True, check=True).stdout
        return [root / p for p in out.decode().split("\0") if p and (root / p).is_file()]
    except (OSError, subprocess.CalledProcessError):
        files = []
        for dirpath, dirnames, filenames in os.walk(root):
            rel = Path(dirpath).relative_to(root)
            if rel.parts and (rel.parts[0].startswith("build") or rel.parts[0] in ("runs", "out", ".git")):
                dirnames[:] = []
                continue
            files += [Path(dirpath) / f for f in filenames]
        return files


def holds_parameters(path):
    """Whether an archive file has solution_* (parameter) columns."""
    try:
        return any(c.startswith("solution_") for c in csv_header(path))
    except (OSError, EOFError, UnicodeDecodeError):
        return False


def check(root, files=None):
    """Failures of the rule for the files tracked under `root` (or `files`, paths under it)."""
    root = Path(root)
    files = tracked_files(root) if files is None else [Path(f) for f in files]
    failures, inside, outside = [], 0, 0
    for f in files:
        rel = f.relative_to(root).as_posix()
        size = f.stat().st_size
        if rel.startswith("results/"):
            inside += size
        else:
            outside += size
        for pattern, what in BULKY:
            if pattern.search(rel):
                failures.append(f"{rel}: {what}; a study keeps only what results/README.md lists")
        if re.search(r"(^|/)archive(-cells)?\.csv(\.gz)?$", rel) and holds_parameters(f):
            failures.append(f"{rel}: an archive with the elites' parameters (solution_* columns); keep it without "
                            "them (share/qdresults does)")
        if rel.startswith("results/") and size > LARGEST_PLAIN and not rel.endswith((".gz", ".png")):
            failures.append(f"{rel}: {size} bytes uncompressed; store it as {Path(rel).name}.gz")
    if inside > BUDGET_RESULTS:
        failures.append(f"results/ tracks {inside} bytes, more than its budget of {BUDGET_RESULTS} (results/README.md)")
    if outside > BUDGET_SOURCE:
        failures.append(f"the tree outside results/ tracks {outside} bytes, more than its budget of {BUDGET_SOURCE}")
    return failures, inside, outside


def gzip_copy(src, dst, lines=None):
    """Writes src (plain text) to dst.gz, reproducibly (no name or time in the gzip header)."""
    with open_text(src) as f, open(dst, "wb") as raw:
        with gzip.GzipFile(filename="", mode="wb", compresslevel=9, fileobj=raw, mtime=0) as z:
            for line in (lines(f) if lines else f):
                z.write(line.encode())


def without_parameters(f):
    """archive.csv's lines without the solution_* columns (which come last)."""
    header = f.readline().rstrip("\n").split(",")
    keep = len([c for c in header if not c.startswith("solution_")])
    if header[keep:] and not all(c.startswith("solution_") for c in header[keep:]):
        raise ValueError("archive.csv: solution_* columns are not the last")
    yield ",".join(header[:keep]) + "\n"
    for line in f:
        yield ",".join(line.rstrip("\n").split(",", keep)[:keep]) + "\n"


def machine_paths(text, replacements):
    for path, name in replacements:
        text = text.replace(path, name)
    return text


def every_kth_row(k):
    """metrics.csv's lines, keeping the header, every row whose iteration + 1 is a multiple of k and
    every loop's last row (so loop ends, where the figures mark loops, stay exact)."""
    def lines(f):
        yield f.readline()
        rows = [line for line in f if line.strip()]
        for i, line in enumerate(rows):
            loop, iteration = line.split(",", 2)[:2]
            last = i + 1 == len(rows) or rows[i + 1].split(",", 1)[0] != loop
            if last or (int(iteration) + 1) % k == 0:
                yield line
    return lines


def thinned_by(values):
    """The k of a study's copy whose metrics.csv already keeps every k-th iteration (its summary.toml
    says so), else 1."""
    m = re.match(r"every (\d+)th iteration", str(values.get("metrics_rows_kept", "")))
    return int(m.group(1)) if m else 1


def slim_run(src, dst, replacements=(), rows=None, archive=True):
    """Copies what a study keeps of the run directory src to dst, with summary.toml holding the
    quantities the report needs from files the study does not keep (report/summary.py, KEPT).
    `rows`: a metrics.csv of more rows keeps every k-th (the fewest k that leaves at most `rows`)
    and each loop's last; the full run's mixing ratio over its last loop is then kept in
    summary.toml. `archive`: whether to keep the final archive (and a CVT archive's centroids).
    src may itself be a study's copy (metrics.csv.gz, archive.csv.gz, summary.toml): its files are
    kept, the quantities of its full run stay those its summary.toml holds, and thinning it again
    keeps exactly the rows that thinning its full run would."""
    dst.mkdir(parents=True, exist_ok=True)
    run = Run(src)
    values = summary.kept(run)  # of a study's copy: its summary.toml, the full run's
    done = thinned_by(values)
    step = math.ceil(len(run.metrics) / rows) if rows and len(run.metrics) > rows else 1
    k = done * step  # a multiple of the copy's k: the rows of the full run thinned by k, all still here
    if step > 1:  # quantities of every row, before the copy keeps fewer
        thinned = dict(summary.mixing_last_loop(run), metrics_rows_of_the_full_run=len(run.metrics))
        values = {**thinned, **values, "metrics_rows_kept": f"every {k}th iteration and every loop's last"}
        values = {key: v for key, v in values.items() if not (isinstance(v, float) and math.isnan(v))}
    if values:
        (dst / summary.SUMMARY).write_text("# From the full run, which kept files this copy does not "
                                            "(report/summary.py, KEPT)\n" +
                                            "".join(f"{key} = {study.toml_value(v)}\n" for key, v in values.items()))
    for name in [*KEEP, *(p.name for p in session_provenance(src))]:
        if (src / name).exists():
            text = (src / name).read_text()
            (dst / name).write_text(machine_paths(text, replacements) if name.endswith(".toml") else text)
    for name in COMPRESS:  # open_text reads NAME or a copy's NAME.gz
        if locate(src / name):
            gzip_copy(src / name, dst / f"{name}.gz", every_kth_row(k) if name == "metrics.csv" and step > 1 else None)
    if archive and locate(src / "archive.csv"):
        gzip_copy(src / "archive.csv", dst / "archive.csv.gz", without_parameters)
        if locate(src / "centroids.csv"):  # a CVT archive's cells: its map needs them
            gzip_copy(src / "centroids.csv", dst / "centroids.csv.gz")


def publish(report_dir, study_dir, rows=None, archives="all"):
    """Copies a qdreport directory into a study: the report's records, every run slimmed, the
    figures the kept files cannot give again (compact). The caller regenerates the report there.
    `rows`: thin long metrics.csv files (slim_run). `archives`: "all" keeps every run's final
    archive, "maps" only those of the runs the maps draw (each group's median run)."""
    report_dir, study_dir = Path(report_dir), Path(study_dir)
    if (study_dir / "runs").exists():
        raise FileExistsError(f"{study_dir} already holds a study")
    study_dir.mkdir(parents=True, exist_ok=True)
    for name in ("study.toml", "estimate.txt", "invocations.csv"):
        if (report_dir / name).exists():
            shutil.copy2(report_dir / name, study_dir / name)
    replacements = [(str(report_dir.resolve()), "REPORT_DIR"), (str(Path.home()), "~")]
    runs = sorted(p.parent for p in (report_dir / "runs").rglob("config.toml") if is_run_dir(p.parent))
    drawn = None
    if archives == "maps":
        groups = group([Run(p) for p in runs])
        drawn = {median_run(rs).path for algs in groups.values() for rs in algs.values()}
    for run in runs:
        slim_run(run, study_dir / "runs" / run.relative_to(report_dir / "runs"), replacements, rows,
                 archive=drawn is None or run in drawn)
    figures = study_dir / "figures"
    figures.mkdir(exist_ok=True)
    kept = []
    for entry in read_manifest(report_dir / "figures"):
        if entry["kind"] in KEPT_FIGURES and entry["format"] == "png":
            compact_png(report_dir / "figures" / entry["file"], figures / entry["file"])
            kept.append(dict(entry, runs=[machine_paths(r, replacements) for r in entry["runs"]]))
    (figures / MANIFEST).write_text(json.dumps({"dpi": 100, "files": kept}, indent=1) + "\n")
    return len(runs), len(kept)

