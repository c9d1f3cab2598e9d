"""qdresults: turn a qdreport directory into a study for results/, or check a repository's rule.

  qdresults REPORT_DIR results/NAME   copy the report's records, each run without its parameters,
           [--rows N] [--archives maps] checkpoints and per-epoch logs (metrics.csv and the archive
                                      compressed), the figures those files cannot give again, then
                                      draw the others and write REPORT.md from the copy; --rows N
                                      keeps every k-th row of a longer metrics.csv (and each loop's
                                      last), --archives maps only the archives the maps draw
  qdresults --check [SOURCE_DIR]      fail (exit 1) when the files git tracks hold a run's bulky files
                                      or exceed the size budgets of results/README.md"""
import argparse
import sys
from pathlib import Path

from . import ToolError, results
from .report_cli import regenerate


def main(argv=None):
    ap = argparse.ArgumentParser(prog="qdresults", description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="check the rule on the files tracked in SOURCE_DIR")
    ap.add_argument("paths", nargs="*", help="REPORT_DIR STUDY_DIR, or with --check the source tree (default: .)")
    ap.add_argument("--rows", type=int, help="keep at most about N rows of each run's metrics.csv: every k-th "
                    "iteration and every loop's last row (default: every row)")
    ap.add_argument("--archives", choices=("all", "maps"), default="all",
                    help="keep every run's final archive (all, the default) or only those the maps draw: each "
                         "environment and algorithm's run of median coverage (maps)")
    args = ap.parse_args(argv)
    try:
        if args.check:
            if len(args.paths) > 1:
                ap.error("--check takes one directory")
            failures, inside, outside = results.check(Path(args.paths[0] if args.paths else "."))
            if failures:
                print("results check FAILED:\n  " + "\n  ".join(failures))
                sys.exit(1)
            print(f"results check ok: {inside} bytes tracked in results/ (budget {results.BUDGET_RESULTS}), "
                  f"{outside} outside (budget {results.BUDGET_SOURCE})")
            return
        if len(args.paths) != 2:
            ap.error("give REPORT_DIR and STUDY_DIR")
        report_dir, study_dir = map(Path, args.paths)
        if not (report_dir / "study.toml").exists():
            raise ToolError(f"{report_dir}: no study.toml (a report of qdreport writes one)")
        try:
            runs, figures = results.publish(report_dir, study_dir, args.rows, args.archives)
        except FileExistsError as e:
            raise ToolError(str(e)) from e
        print(f"qdresults: {runs} runs and {figures} figures copied into {study_dir}")
        regenerate(study_dir)
    except ToolError as e:
        sys.exit(f"qdresults: {e}")
