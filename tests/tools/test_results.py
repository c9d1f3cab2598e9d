"""qdtools.results: what a study keeps of a run, and the check that fails when a repository
commits a run's bulky files (the test command runs it on this repository: results.check)."""
import gzip
import shutil
import subprocess
import unittest
from unittest import mock

import fixtures

from qdtools import results, runs
from qdtools.report import summary


def git(repo, *args):
    subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True)


class Check(unittest.TestCase):
    def setUp(self):
        self.repo = fixtures.tmpdir(self)
        git(self.repo, "init", "-q")
        (self.repo / "README.md").write_text("source\n")

    def commit_run(self, name, slim):
        run = fixtures.write_run(self.repo / "results" / "study" / "src", archive=[(1, 0.5, 0.1, 0.2)])
        dest = self.repo / "results" / "study" / "runs" / name
        if slim:
            results.slim_run(run, dest)
        else:
            shutil.copytree(run, dest)
            (dest / "losses.csv").write_text("loop,epoch,train_loss,test_loss\n0,0,1,\n")
            (dest / "checkpoint.bin").write_bytes(b"\0" * 10)
        shutil.rmtree(run.parent.parent)
        git(self.repo, "add", "-A")
        return dest

    def test_a_slim_study_passes(self):
        self.commit_run("point-mass-iso/seed-1", slim=True)
        failures, inside, outside = results.check(self.repo)
        self.assertEqual(failures, [])
        self.assertEqual(outside, len("source\n"))
        self.assertGreater(inside, 0)

    def test_bulky_files_fail(self):
        self.commit_run("point-mass-iso/seed-1", slim=False)
        failures = "\n".join(results.check(self.repo)[0])
        self.assertIn("seed-1/losses.csv: per-epoch training log", failures)
        self.assertIn("seed-1/checkpoint.bin: checkpoint", failures)
        self.assertIn("seed-1/archive.csv: an archive with the elites' parameters", failures)

    def test_only_tracked_files_count(self):
        (self.repo / "losses.csv").write_text("not committed\n")
        self.assertEqual(results.check(self.repo)[0], [])

    def test_budgets_and_large_plain_files(self):
        big = self.repo / "results" / "study" / "notes.txt"
        big.parent.mkdir(parents=True)
        big.write_text("x" * (results.LARGEST_PLAIN + 1))
        git(self.repo, "add", "-A")
        self.assertIn("uncompressed; store it as notes.txt.gz", results.check(self.repo)[0][0])
        with mock.patch.object(results, "BUDGET_SOURCE", 3):
            self.assertTrue(any("outside results/ tracks 7 bytes, more than its budget of 3" in f
                                for f in results.check(self.repo)[0]))


class Slim(unittest.TestCase):
    def test_keeps_what_a_reader_needs_and_drops_the_parameters(self):
        root = fixtures.tmpdir(self)
        run = fixtures.write_run(root / "full", archive=[(1, 0.5, 0.1, 0.2), (4, 0.7, 0.3, 0.4)],
                                 grid=([5], ["x"], [0], [1]))
        (run / "losses.csv").write_text("loop,epoch\n")
        (run / "dataset.bin").write_bytes(b"\1")
        results.slim_run(run, root / "slim")
        kept = sorted(p.name for p in (root / "slim").iterdir())
        self.assertEqual(kept, ["archive.csv.gz", "config.toml", "grid.toml", "metrics.csv.gz", "provenance.toml",
                                "status", "summary.toml"])
        # The elites' parameter norms, which need the parameters the copy drops: (0.5, -0.5) each.
        norms = runs.read_toml(root / "slim" / "summary.toml")
        self.assertAlmostEqual(norms["parameter_norm_median"], 0.5 ** 0.5)
        self.assertAlmostEqual(norms["parameter_norm_max"], 0.5 ** 0.5)
        with gzip.open(root / "slim" / "archive.csv.gz", "rt") as f:
            self.assertEqual(f.read(), "index,objective,measures_0,measures_1,recn_error\n1,0.5,0.1,0.2,0\n"
                                       "4,0.7,0.3,0.4,0\n")
        self.assertEqual(repr(runs.read_csv(root / "slim" / "metrics.csv")), repr(runs.read_csv(run / "metrics.csv")))
        a, b = runs.Run(run), runs.Run(root / "slim")
        self.assertEqual((a.algorithm, a.final_elites(), a.cells), (b.algorithm, b.final_elites(), b.cells))
        self.assertEqual(runs.read_archive(root / "slim").cells.tolist(), [1, 4])
        first = (root / "slim" / "metrics.csv.gz").read_bytes()
        results.slim_run(run, root / "again")
        self.assertEqual((root / "again" / "metrics.csv.gz").read_bytes(), first)  # reproducible bytes

    def test_long_metrics_keep_every_kth_row_and_every_loop_end(self):
        root = fixtures.tmpdir(self)
        # Loop 0, then loops 1 and 2 of 7 iterations each: 15 rows; at most 6 rows kept -> every 3rd iteration.
        rows = [(0, 10, 1, "")] + [(L, 10 + 10 * (7 * (L - 1) + i + 1), 2 + i, 0.1 * i) for L in (1, 2) for i in range(7)]
        run = fixtures.write_run(root / "full", metrics=rows, archive=[(1, 0.5, 0.1, 0.2)])
        results.slim_run(run, root / "slim", rows=6)
        kept = runs.Run(root / "slim")
        self.assertEqual([(m["loop"], m["iteration"]) for m in kept.metrics],
                         [(0, 0), (1, 2), (1, 5), (1, 6), (2, 2), (2, 5), (2, 6)])
        full, slim = summary.summarise(runs.Run(run)), summary.summarise(kept)
        self.assertAlmostEqual(slim["mixing"], full["mixing"])  # the full last loop's mean, from summary.toml
        self.assertAlmostEqual(full["mixing"], 0.3)
        self.assertEqual((slim["elites"], slim["evaluations"], slim["loop_rates"]),
                         (full["elites"], full["evaluations"], full["loop_rates"]))  # loop ends are all kept
        self.assertEqual(runs.read_toml(root / "slim" / "summary.toml")["metrics_rows_of_the_full_run"], 15)

    def test_a_studys_copy_keeps_its_files_and_thins_as_its_full_run_would(self):
        # qdresults over a study (say, to keep fewer rows of its older runs) once dropped the copies'
        # metrics and archives, which it looked for only uncompressed.
        root = fixtures.tmpdir(self)
        rows = [(0, 10, 1, "")] + [(L, 10 + 10 * (12 * (L - 1) + i + 1), 2 + i, 0.1 * i) for L in (1, 2) for i in range(12)]
        full = fixtures.write_run(root / "full", metrics=rows, archive=[(1, 0.5, 0.1, 0.2), (4, 0.7, 0.3, 0.4)])
        results.slim_run(full, root / "copy")
        results.slim_run(root / "copy", root / "copy-of-copy")
        for name in ("archive.csv.gz", "metrics.csv.gz", "summary.toml", "config.toml"):
            self.assertEqual((root / "copy-of-copy" / name).read_bytes(), (root / "copy" / name).read_bytes(), name)
        # Thinned in two steps (every 2nd, then to at most 8 rows) = thinned once by the product.
        results.slim_run(full, root / "by-2", rows=13)
        results.slim_run(root / "by-2", root / "by-2-then-2", rows=8)
        results.slim_run(full, root / "by-4", rows=7)
        kept = runs.Run(root / "by-2-then-2")
        self.assertEqual([(m["loop"], m["iteration"]) for m in kept.metrics],
                         [(0, 0), (1, 3), (1, 7), (1, 11), (2, 3), (2, 7), (2, 11)])
        for name in ("metrics.csv.gz", "archive.csv.gz"):
            self.assertEqual((root / "by-2-then-2" / name).read_bytes(), (root / "by-4" / name).read_bytes(), name)
        told = runs.read_toml(root / "by-2-then-2" / "summary.toml")
        self.assertEqual(told, runs.read_toml(root / "by-4" / "summary.toml"))
        self.assertEqual(told["metrics_rows_of_the_full_run"], 25)  # the full run's, not the copy's 13
        self.assertEqual(told["metrics_rows_kept"], "every 4th iteration and every loop's last")
        self.assertAlmostEqual(told["mixing"], 0.55)  # the full last loop's mean (0.0 .. 1.1)
        self.assertAlmostEqual(told["parameter_norm_median"], 0.5 ** 0.5)  # needs parameters no copy has

    def test_a_resumed_runs_sessions_are_kept_and_named(self):
        root = fixtures.tmpdir(self)
        run = fixtures.write_run(root / "full", archive=[(1, 0.5, 0.1, 0.2)])
        full = summary.summarise(runs.Run(run))
        self.assertEqual((full["git"], full["built_for"]), ("abc", "CPU, -march=x"))
        # Loops 12 on by another revision on another CPU, loops 3-11 by the same build (no new name).
        (run / "provenance-resume-loop-12.toml").write_text(f'git_revision = "def"\ncpu = "Other CPU"\n'
                                                            f'instruction_set = "-march=y"\ncommand = "{run}/x"\n')
        (run / "provenance-resume-loop-3.toml").write_text((run / "provenance.toml").read_text())
        (run / "provenance-resume-loop-x.toml").write_text("not = 'a session'\n")
        results.slim_run(run, root / "slim", replacements=[(str(run), "REPORT_DIR")])
        self.assertEqual(sorted(p.name for p in (root / "slim").glob("provenance*")),
                         ["provenance-resume-loop-12.toml", "provenance-resume-loop-3.toml", "provenance.toml"])
        self.assertEqual(runs.read_toml(root / "slim" / "provenance-resume-loop-12.toml")["command"], "REPORT_DIR/x")
        slim = summary.summarise(runs.Run(root / "slim"))
        self.assertEqual(slim["git"], "abc then def")
        self.assertEqual(slim["built_for"], "CPU, -march=x then Other CPU, -march=y")

    def test_archives_only_for_the_maps(self):
        report = fixtures.tmpdir(self) / "report"
        for seed, elites in ((1, 9), (2, 5), (3, 7)):  # the median final coverage: seed 3
            fixtures.write_run(report / "runs", seed=seed, metrics=[(0, 10, 2), (1, 20, elites)],
                               archive=[(1, 0.5, 0.1, 0.2)])
        (report / "study.toml").write_text("[selection]\n")
        results.publish(report, report.parent / "study", archives="maps")
        kept = sorted(p.parent.name for p in (report.parent / "study" / "runs").rglob("archive.csv.gz"))
        self.assertEqual(kept, ["seed-3"])

    def test_a_cvt_keeps_its_centroids_compressed(self):
        root = fixtures.tmpdir(self)
        run = fixtures.write_run(root / "full", centroids=(["x", "y"], [(0.0, 0.0), (1.0, 0.5)]),
                                 archive=[(1, 0.5, 0.9, 0.4)])
        results.slim_run(run, root / "slim")
        self.assertIn("centroids.csv.gz", [p.name for p in (root / "slim").iterdir()])
        self.assertEqual(runs.read_grid(root / "slim").centroids.tolist(), [[0.0, 0.0], [1.0, 0.5]])
        self.assertEqual(runs.Run(root / "slim").algorithm, "my-env-decaying")  # its experiment

    def test_quantities_of_the_full_run_are_kept_in_summary_toml(self):
        root = fixtures.tmpdir(self)
        run = fixtures.write_run(root / "full", archive=[(1, 0.5, 0.1, 0.2), (4, 0.7, 0.3, 0.4)])

        def largest_parameter(r):  # needs the parameters, which a study does not keep
            rows = runs.read_csv(r.path / "archive.csv")
            return {"largest_parameter": max(abs(v) for row in rows for k, v in row.items() if k.startswith("solution_"))}

        with mock.patch.object(summary, "KEPT", [largest_parameter]):
            results.slim_run(run, root / "slim")
            self.assertEqual(runs.read_toml(root / "slim" / "summary.toml"), {"largest_parameter": 0.5})
            self.assertEqual(summary.summarise(runs.Run(root / "slim"))["largest_parameter"], 0.5)
            self.assertEqual(summary.summarise(runs.Run(run))["largest_parameter"], 0.5)


if __name__ == "__main__":
    unittest.main()
