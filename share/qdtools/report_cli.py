"""qdreport: reproduce the PoMS paper's comparison on a chosen budget and write a Markdown report.

Runs the 8 algorithms on the chosen environments over a list of seeds through a qdrun sweep (finished
runs are skipped, interrupted ones resumed: run the same command again after an interruption), calls
qdplot, and writes REPORT.md with the figures, the final coverage per algorithm (median and
quartiles over seeds, in cells and percent; the Walker's also in % of 50 000), wall time,
evaluations per second and the PoMS mixing ratio per run, the machine, budget and git revision, and
the sweep's dry-run estimate (kept in estimate.txt before the first run) against the measured time.
study.toml beside it records what the runs do not say; --regenerate DIR makes the figures and the
report again from a directory's files alone (a study in results/), without qdrun.

Examples. The paper (its budgets and 5 seeds; CPU-days):
  qdreport --environments striker,bipedal-walker,bipedal-kicker --seeds 100,200,300,400,500 -o report/
A quicker look, ~100k evaluations per run (the report states the budget):
  qdreport --environments striker,bipedal-kicker --seeds 100,200,300 --evaluations 102000 -o report/
Add --dry-run to print the plan and its estimated core-hours (qdrun --dry-run) without running.
There is no autoencoder epoch cap unless --max-epochs N is given; a cap is then stated in the
report's header, beside every table it affects, and on every figure of a capped run.
"""
import argparse
import contextlib
import io
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

from . import ToolError, plot_cli, runs as runs_mod, tables
from .figures.output import read_manifest
from .qdrun import find_qdrun, version
from .report import sections, study, summary, sweep
from .report.commands import Shown

FILE_KINDS = "coverage,qd,maps,losses"  # the figures a directory's files alone give (no qdrun)


def parser():
    algs = tables.algorithms()
    ap = argparse.ArgumentParser(prog="qdreport", description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 2)[2], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--environments", default="striker,bipedal-kicker",
                    help="comma list of the environment variants of the experiment directory (its subdirectories: "
                         "striker, bipedal-walker, bipedal-kicker and their -mix-scale versions, or another directory "
                         "there such as lp-sphere with --algorithms naming its files; default: striker,bipedal-kicker)")
    ap.add_argument("--algorithms", default=",".join(algs.experiments),
                    help="comma list of experiment file stems: the paper's 8 (the default), or any file every chosen "
                         "environment's directory has (cma-me for experiments/lp-sphere, say)")
    ap.add_argument("--seeds", default="100,200,300", help="seed list, as qdrun --seeds (default: 100,200,300)")
    ap.add_argument("--evaluations", type=int, help="budget per run (qdrun --evaluations; default: the files' own, "
                    "the paper's: 1 002 000 for the Striker, 2 002 000 for Walker and Kicker; CPU-days)")
    ap.add_argument("--loops", type=int, help="budget as experiment.loops for every run instead (note: a PS loop "
                    "is 2000 evaluations, a MAP-Elites loop 20 000)")
    ap.add_argument("--max-epochs", type=int, help="cap autoencoder epochs per loop (representation.max_epochs; "
                    "default: no cap, the paper's 20 000 with early stopping); a cap is stated in the report, beside "
                    "every table and on every figure it affects")
    ap.add_argument("--set", action="append", default=[], help="extra qdrun --set for every run (repeatable)")
    ap.add_argument("--jobs", type=int, help="concurrent runs (qdrun --jobs; default: all cores)")
    ap.add_argument("--note", action="append", default=[],
                    help="a sentence for the report's notes (repeatable), e.g. what else used the machine")
    ap.add_argument("-o", "--output", default="report", help="report directory: runs/, figures/, REPORT.md")
    ap.add_argument("--configs", choices=("reference", "paper-text"), default="reference",
                    help="which experiment files: 'reference' (default), the reference code's configurations, which "
                         "made the paper's figures (experiments/reference/); 'paper-text', the paper's text "
                         "(experiments/<environment>/). experiments/README.md lists their differences; the report "
                         "names the set")
    ap.add_argument("--experiments", help="experiment directory holding the set (default: the one installed beside "
                    "qdreport)")
    ap.add_argument("--qdrun", help="qdrun executable (default: $QDRUN, <prefix>/bin, PATH, build/bin)")
    ap.add_argument("--no-run", action="store_true", help="only plot and write the report from the runs there")
    ap.add_argument("--dry-run", action="store_true", help="print the sweep's plan and its estimated core-hours "
                    "(qdrun --dry-run), run nothing, write nothing")
    ap.add_argument("--regenerate", metavar="DIR", help="make DIR's figures and REPORT.md again from its files and "
                    "study.toml alone (no qdrun, no run): a study in results/; other options are ignored")
    return ap


def config_set(directory):
    """('reference' or 'paper-text', the run-name prefix) of a directory of experiment files, read from
    its Striker PoMS file's experiment name ("reference-striker-poms" or "striker-poms")."""
    with open(Path(directory) / "striker" / "poms.toml", "rb") as f:
        name = tomllib.load(f).get("experiment", {}).get("name", "")
    prefix = name[:-len("striker-poms")] if name.endswith("striker-poms") else ""
    return ("reference" if prefix == "reference-" else "paper-text"), prefix


def find_experiments(explicit, configs="paper-text"):
    """The directory of the chosen set's files: DIR/reference or DIR itself, DIR the one given or the
    experiments/ installed beside the tools."""
    share = tables.SHARE
    for c in (explicit, share / "experiments", share.parent / "experiments"):
        if not c:
            continue
        for d in ((Path(c) / "reference", Path(c)) if configs == "reference" else (Path(c),)):
            if (d / "striker" / "poms.toml").exists() and config_set(d)[0] == configs:
                return d
        if explicit:
            break
    where = f" in {explicit}" if explicit else ""
    raise ToolError(f"cannot find the experiment files of the {configs} set{where} (--experiments DIR: a directory "
                    f"with striker/poms.toml{', or with reference/striker/poms.toml' if configs == 'reference' else ''})")


def main(argv=None):
    try:
        sys.exit(run(argv))
    except ToolError as e:
        sys.exit(f"qdreport: {e}")


def run(argv=None):
    ap = parser()
    args = ap.parse_args(argv)
    if args.regenerate:
        return regenerate(Path(args.regenerate))
    qdrun = find_qdrun(args.qdrun)
    if not qdrun and not args.no_run:
        raise ToolError("qdrun not found (--qdrun or $QDRUN)")
    exp_dir = find_experiments(args.experiments, args.configs)
    configs, prefix = config_set(exp_dir)
    known_envs = tables.experiment_variants(exp_dir)
    envs = [e for e in args.environments.split(",") if e]
    algs = [a for a in args.algorithms.split(",") if a]
    for e in envs:  # the paper's variants, or any directory of the set (a benchmark's: lp-sphere)
        if e not in known_envs and not (exp_dir / e).is_dir():
            ap.error(f"unknown environment '{e}' (known: {', '.join(known_envs)}, or a directory of {exp_dir})")
    for a in algs:  # the paper's algorithms, or any experiment file that every chosen environment has
        missing = [e for e in envs if not (exp_dir / e / f"{a}.toml").exists()]
        if missing and a not in tables.algorithms().experiments:
            ap.error(f"unknown algorithm '{a}': no {a}.toml in {', '.join(str(exp_dir / e) for e in missing)} "
                     f"(the paper's: {', '.join(tables.algorithms().experiments)})")
    if args.evaluations is not None and args.loops is not None:
        ap.error("--evaluations and --loops conflict")
    if args.dry_run and args.no_run:
        ap.error("--dry-run and --no-run conflict")
    out = Path(args.output)
    runs_root = out / "runs"
    shown = Shown(out, qdrun)
    files = [exp_dir / e / f"{a}.toml" for e in envs for a in algs]
    command = sweep.command(qdrun or "qdrun", files, args.seeds, runs_root, args.evaluations, args.loops,
                            args.max_epochs, args.set, args.jobs)
    if args.dry_run:
        print("qdreport: " + shlex.join(command + ["--dry-run"]), flush=True)
        return subprocess.run(command + ["--dry-run"]).returncode
    out.mkdir(parents=True, exist_ok=True)
    rc, sweep_line = 0, None
    if not args.no_run:
        if not (out / "estimate.txt").exists():  # the plan and its cost before the first run
            sweep.save_estimate(out, command, shown)
        rc, seconds, summary_line = sweep.run(out, command)
        sweep_line = (f"`{shown(command)}`, exit code {rc}, {seconds / 60:.1f} min wall ({summary_line}; skipped runs "
                      "were made by an earlier invocation)")
    record = study.read(out) or {}
    header = dict(study.this_machine(), qdrun=version(qdrun), sweep=sweep_line, command=shown(sys.argv),
                  commands_from=shown.origin(), notes=args.note)
    for hand in ("title", "preface"):  # written by hand into study.toml: kept
        if record.get("header", {}).get(hand):
            header[hand] = record["header"][hand]
    selection = {"environments": envs, "algorithms": algs, "seeds": args.seeds, "evaluations": args.evaluations,
                 "loops": args.loops, "max_epochs": args.max_epochs, "set": args.set, "configs": configs,
                 "prefix": prefix}
    study.write(out, {"selection": selection, "header": header, "addendum": record.get("addendum", [])})
    draw(out, kinds=None, qdrun=qdrun)
    write(out, selection, header, record.get("addendum", []))
    return 1 if rc else 0


def draw(out, kinds=None, qdrun=None, compact=False):
    """qdplot on the report's runs into figures/ (its output kept quiet)."""
    kinds = (kinds or ",".join(plot_cli.KINDS)).split(",")
    runs_root = out / "runs"
    if not runs_root.is_dir() or not any(runs_mod.is_run_dir(p.parent) for p in runs_root.rglob("config.toml")):
        raise ToolError(f"{runs_root}: holds no run directories")
    print(f"qdreport: qdplot {runs_root} -o {out / 'figures'} --kinds {','.join(kinds)}", flush=True)
    with contextlib.redirect_stdout(io.StringIO()):
        plot_cli.plot([runs_root], out / "figures", kinds, formats=("png", "svg") if not compact else ("png",),
                      qdrun=qdrun, compact=compact)


def against_budget(s, selection):
    """A run that is complete at its own budget but short of the report's (a run being extended, say
    from 302 000 to 1 000 200 evaluations) is not complete for this report: its status says so."""
    if s["status"] != "complete" or not s["run"].metrics:
        return s
    loops_reached = int(s["run"].metrics[-1]["loop"]) + 1
    loops, evaluations = selection.get("loops"), selection.get("evaluations")
    if loops and loops_reached < loops:
        s["status"] = f"complete at {loops_reached} loops, short of this report's {loops}"
    elif evaluations and s["evaluations"] < evaluations:
        s["status"] = f"complete at {s['evaluations']} evaluations, short of this report's {evaluations}"
    return s


def render(out, selection, header, addenda):
    """REPORT.md's text for the report directory `out`: its runs, figures/qdplot.json and these."""
    runs_root = out / "runs"
    envs, algs = selection["environments"], selection["algorithms"]
    # Every run of the chosen environments and algorithms: the epoch caps are read from the runs themselves.
    prefix = selection.get("prefix", "")  # the reference set's runs are named reference-<env>-<alg>
    found = {(e, a): [against_budget(summary.summarise(runs_mod.Run(d)), selection)
                      for d in sorted((runs_root / f"{prefix}{e}-{a}").glob("seed-*"), key=lambda d: d.name)
                      if runs_mod.is_run_dir(d)] for e in envs for a in algs}
    report = sections.Report(out=out, envs=envs, algs=algs, runs=found, figures=read_manifest(out / "figures"),
                             header=header, selection=selection, addenda=addenda)
    return sections.render(report)


def write(out, selection, header, addenda):
    tmp = out / "REPORT.md.tmp"
    tmp.write_text(render(out, selection, header, addenda))
    tmp.replace(out / "REPORT.md")
    print(f"qdreport: wrote {out / 'REPORT.md'}")


def regenerated(out):
    """The header and addenda of a report made again from its study.toml (--regenerate)."""
    record = study.read(out)
    if record is None:
        raise ToolError(f"{out}: no {study.NAME} (qdreport writes one with every report; see share/README.md)")
    header = dict(record["header"], regenerated=Shown(out)([tables.SHARE / "qdreport", "--regenerate", out]))
    return record["selection"], header, record.get("addendum", [])


def regenerate(out):
    selection, header, addenda = regenerated(out)
    draw(out, kinds=FILE_KINDS, compact=True)
    write(out, selection, header, addenda)
    return 0
