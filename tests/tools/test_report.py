"""qdreport's parts: the study record, the sections and their addenda, commands without this
machine's paths, and a report regenerated from a directory's files alone."""
import sys
import unittest

import fixtures

from qdtools import report_cli
from qdtools.report import commands, study, sweep
from qdtools.report.summary import summarise
from qdtools.runs import Run

ALG_PAIRS = {"poms": ("autoencoder", "poms"), "iso": ("none", "iso")}


def make_study(out, elites):
    """Runs of striker-<alg>/seed-<s> with the given final elites, and their study.toml."""
    for (alg, seed), n in elites.items():
        rep, mut = ALG_PAIRS[alg]
        fixtures.write_run(out / "runs", name=f"striker-{alg}", seed=seed, env="striker", rep=rep, mutator=mut,
                           descriptor="striker-contacts",
                           metrics=[(0, 20, n // 2, 0.5 if alg == "poms" else ""),
                                    (1, 40, n, 0.25 if alg == "poms" else "")])
    study.write(out, {"selection": {"environments": ["striker"], "algorithms": ["poms", "iso"], "seeds": "1,2,3",
                                    "evaluations": 40},
                      "header": {"date": "2026-01-01 00:00 UTC", "qdrun": "qdrun 9 (git x)", "machine": "M",
                                 "hardware_threads": 7, "command": "share/qdreport -o REPORT_DIR",
                                 "notes": ["a note"], "preface": "> By hand."},
                      "addendum": [{"after": "## striker", "text": "Added under striker.\n"}]})


def regenerate(out):
    """qdreport --regenerate OUT (as run from the repository); REPORT.md's text."""
    argv, sys.argv = sys.argv, ["share/qdreport"]
    try:
        report_cli.regenerate(out)
    finally:
        sys.argv = argv
    return (out / "REPORT.md").read_text()


class Regenerate(unittest.TestCase):
    def test_tables_from_the_files_alone(self):
        out = fixtures.tmpdir(self) / "study"
        make_study(out, {("poms", 1): 30, ("poms", 2): 10, ("poms", 3): 20, ("iso", 1): 40, ("iso", 2): 50})
        text = regenerate(out)
        self.assertTrue(text.startswith("# PoMS reproduction report\n\n> By hand.\n\n- date: 2026-01-01 00:00 UTC\n"))
        self.assertIn("- note: a note\n", text)
        self.assertIn("on this machine with 7 hardware threads", text)
        # 100 cells (no grid.toml): the median of (10, 20, 30) is 20; of (40, 50) it is 40 (rank 0.5 rounds to
        # even, 0) and the 75th percentile 50 (rank 0.75 -> 1); PoMS's mixing ratio over its last loop.
        self.assertIn("| PoMS | 3/3 | 40 | 20 (10-30) | 20.00 (10.00-30.00) |", text)
        self.assertIn("| MAPE-Iso | 2/2 | 40 | 40 (40-50) | 40.00 (40.00-50.00) |", text)
        self.assertRegex(text, r"\| PoMS \| 3/3 .* \| 0\.25 \| 20000 \(paper\) \|")
        self.assertIn("![coverage striker](figures/coverage-striker.png)", text)
        body = text.split("## striker", 1)[1]
        self.assertIn("</details>\n\nAdded under striker.\n\n## Diagnostics", body)
        self.assertTrue((out / "figures" / "coverage-striker.png").exists())
        self.assertFalse((out / "figures" / "coverage-striker.svg").exists())  # a study keeps PNGs
        self.assertIn("\nQD metrics: no task fitness (the environment declares none", body)
        self.assertFalse((out / "figures" / "qd-striker.png").exists())

    def test_which_algorithm_leads_ours_beside_the_papers(self):
        out = fixtures.tmpdir(self) / "study"
        # Elites (of 100 cells, so %) at 20 000 and 50 000 evaluations. Ours at 20 000: PoMS's median of
        # (10, 12, 14) is 12, MAPE-Iso's of (8, 9) is 8 (rank 0.5 rounds to even): PoMS leads by 12/8 - 1.
        # At 50 000: 16 against 20, MAPE-Iso leads by 25 %. The paper's Striker curves (share/paper-curves.csv)
        # have MAPE-Iso ahead at both: 6.108 against 5.510 (10.9 %), 7.807 against 7.288 (7.1 %).
        for alg, seeds in {"poms": ((10, 15), (12, 16), (14, 17)), "iso": ((8, 20), (9, 30))}.items():
            rep, mut = ALG_PAIRS[alg]
            for seed, (at20, at50) in enumerate(seeds, 1):
                fixtures.write_run(out / "runs", name=f"striker-{alg}", seed=seed, env="striker", rep=rep,
                                   mutator=mut, descriptor="striker-contacts",
                                   metrics=[(0, 20000, at20, ""), (1, 50000, at50, "")])
        study.write(out, {"selection": {"environments": ["striker"], "algorithms": ["poms", "iso"], "seeds": "1,2,3",
                                        "evaluations": 50000},
                          "header": {"date": "2026-01-01 00:00 UTC", "qdrun": "qdrun 9 (git x)", "machine": "M",
                                     "hardware_threads": 2, "command": "share/qdreport -o REPORT_DIR"}})
        text = regenerate(out)
        self.assertIn("| PoMS | 12.00 / 5.51 = 2.18 (3) | 16.00 / 7.29 = 2.20 (3) |", text)
        self.assertIn("| 20 000 | PoMS 12.00 (3) | MAPE-Iso 8.00 (2) | 50.0 % | MAPE-Iso 6.11 | PoMS 5.51 | 10.9 % | no |",
                      text)
        self.assertIn("| 50 000 | MAPE-Iso 20.00 (2) | PoMS 16.00 (3) | 25.0 % | MAPE-Iso 7.81 | PoMS 7.29 | 7.1 % | yes |",
                      text)
        # Seed by seed: at 20 000 PoMS leads in seeds 1 and 2 (10 / 8, 12 / 9), where the paper's leader,
        # MAPE-Iso, places second; seed 3 has PoMS alone, so no row. At 50 000 MAPE-Iso leads in both.
        self.assertIn("| at | seed | PoMS | MAPE-Iso | leader | lead | the paper's leader's place |", text)
        self.assertIn("| 20 000 | seed 1 | 10.00 | 8.00 | PoMS | 25.0 % over MAPE-Iso | 2 of 2 |\n"
                      "| 20 000 | seed 2 | 12.00 | 9.00 | PoMS | 33.3 % over MAPE-Iso | 2 of 2 |\n"
                      "| 20 000 | the paper's curves | 5.51 | 6.11 | MAPE-Iso | 10.9 % over PoMS | 1 of 2 |\n"
                      "| 50 000 | seed 1 | 15.00 | 20.00 | MAPE-Iso | 33.3 % over PoMS | 1 of 2 |\n"
                      "| 50 000 | seed 2 | 16.00 | 30.00 | MAPE-Iso | 87.5 % over PoMS | 1 of 2 |\n"
                      "| 50 000 | the paper's curves | 7.29 | 7.81 | MAPE-Iso | 7.1 % over PoMS | 1 of 2 |\n", text)
        self.assertNotIn("| seed 3 |", text)

    def test_episode_lengthening_per_algorithm(self):
        out = fixtures.tmpdir(self) / "study"
        # 20 evaluations per loop. PoMS: 0.2 s in loop 0, then 0.4 and 0.8 s: 2x and 4x loop 0's time per
        # evaluation. MAPE-Iso: 0.2 s every loop, 1x. The mean over both runs: 1.5x and 2.5x.
        # Cells: PoMS 5, 9, 12 at the loops' ends, MAPE-Iso 5, 13, 20.
        for alg, wall, elites in (("poms", [0.2, 0.6, 1.4], [5, 9, 12]), ("iso", [0.2, 0.4, 0.6], [5, 13, 20])):
            rep, mut = ALG_PAIRS[alg]
            fixtures.write_run(out / "runs", name=f"striker-{alg}", seed=1, env="striker", rep=rep, mutator=mut,
                               descriptor="striker-contacts", metrics=list(zip((0, 1, 2), (20, 40, 60), elites)),
                               wall=wall)
        # The report's budget is beyond the runs' (runs being extended): they count for the loops they have.
        study.write(out, {"selection": {"environments": ["striker"], "algorithms": ["poms", "iso"], "seeds": "1",
                                        "evaluations": 100},
                          "header": {"date": "2026-01-01 00:00 UTC", "qdrun": "qdrun 9 (git x)", "machine": "M",
                                     "hardware_threads": 2, "command": "share/qdreport -o REPORT_DIR"}})
        text = regenerate(out).split("## Episode lengthening", 1)[1]
        self.assertIn("| evaluations at its middle | 30 | 50 |\n| time per evaluation / loop 0's | 1.50 | 2.50 |\n"
                      "| PoMS (1 run) | 2.00 | 4.00 |\n| MAPE-Iso (1 run) | 1.00 | 1.00 |\n", text)
        # Cells found by each loop's middle, PoMS (5 + 9) / 2 = 7 and (9 + 12) / 2 = 10.5, MAPE-Iso 9 and 16.5;
        # their mean 8 and 13.5, rounded half up.
        self.assertIn("evaluations = [0, 30, 50]\noffspring_time = [1.0, 1.50, 2.50]\ncells = [0, 8, 14]\n", text)
        own = text.split("<details><summary>Each algorithm's own [cost] table</summary>", 1)[1].split("</details>")[0]
        self.assertIn("PoMS:\n\n```toml\n[cost]\nevaluations = [0, 30, 50]\noffspring_time = [1.0, 2.00, 4.00]\n"
                      "cells = [0, 7, 11]\n```", own)
        self.assertIn("MAPE-Iso:\n\n```toml\n[cost]\nevaluations = [0, 30, 50]\noffspring_time = [1.0, 1.00, 1.00]\n"
                      "cells = [0, 9, 17]\n```", own)

    def test_a_run_short_of_the_reports_budget_is_not_complete(self):
        # A run complete at its own budget (20 evaluations) in a report of 40, as a run being extended.
        out = fixtures.tmpdir(self) / "study"
        make_study(out, {("poms", 1): 30, ("poms", 2): 10, ("iso", 1): 40})
        fixtures.write_run(out / "runs", name="striker-poms", seed=3, env="striker", rep="autoencoder",
                           mutator="poms", descriptor="striker-contacts", metrics=[(0, 20, 90, 0.5)])
        text = regenerate(out)
        self.assertIn("| PoMS | 2/3 | 40 | 10 (10-30) |", text)
        self.assertRegex(text, r"\| PoMS \| 3 \| 3 \| 20 \| 90 \| .* \| complete at 20 evaluations, short of this "
                               r"report's 40 \|")
        record = study.read(out)
        record["selection"].update(evaluations=None, loops=2)
        study.write(out, record)
        self.assertRegex(regenerate(out), r"\| PoMS \| 3 \| 3 \| 20 \| 90 \| .* \| complete at 1 loops, short of this "
                                          r"report's 2 \|")

    def test_the_cost_of_a_run_with_two_workers_is_its_episodes_halved_plus_its_training(self):
        out = fixtures.tmpdir(self) / "study"
        make_study(out, {("poms", 1): 30, ("poms", 2): 10, ("iso", 1): 40})
        prov = out / "runs" / "striker-poms" / "seed-2" / "provenance.toml"
        prov.write_text(prov.read_text().replace("workers = 1", "workers = 2"))
        (out / "estimate.txt").write_text(
            "# header\nestimate (...):\n"
            "  striker-poms/seed-1   0.30 core-h: 40 evaluations 0.20 h, training 0.10 h (loop 0: ...)\n"
            "  striker-poms/seed-2   0.30 core-h: 40 evaluations 0.20 h, training 0.10 h (loop 0: ...)\n"
            "  striker-iso/seed-1    0.25 core-h: 40 evaluations 0.25 h, training 0.000 h (loop 0: ...)\n"
            "sweep: estimated 0.85 core-hours (episodes 0.65); on this machine, 1 at a time on 2 cores: about 0.43 hours\n")
        text = regenerate(out)
        # Seed 1 (one worker): 0.30 h; seed 2 (two workers): 0.20 / 2 + 0.10 = 0.20 h; the median of the two is
        # 0.20 (nearest rank rounds to even). Each run's wall time is 0.2 s (two metrics rows).
        self.assertIn("| striker | PoMS | 2 | 0.300 | 0.200 | 0.000 | 0.00 |", text)
        self.assertIn("| striker | MAPE-Iso | 1 | 0.250 | 0.250 | 0.000 | 0.00 |", text)
        self.assertIn("All 3 compared runs: estimate 0.85 core-h, 0.75 h of run wall time with their workers;", text)

    def test_qd_metrics_of_a_task_with_fitness(self):
        out = fixtures.tmpdir(self) / "study"
        # (seed, final QD score) of MAP-Elites (iso) and CMA-ME, an experiment file the table does not know.
        for alg, rep_mut, finals in (("iso", ("none", "iso"), (300.0, 100.0, 200.0)),
                                     ("cma-me", ("none", "cma-me"), (400.0, 500.0))):
            for seed, final in enumerate(finals, 1):
                fixtures.write_run(out / "runs", name=f"lp-sphere-{alg}", seed=seed, env="lp-sphere", rep=rep_mut[0],
                                   mutator=rep_mut[1], descriptor="lp-measures", experiment_file=f"/e/{alg}.toml",
                                   metrics=[(0, 20, 5), (1, 40, 9)], qd=[(10.0, 3.0, 2.0), (final, final / 4, 2.5)])
        study.write(out, {"selection": {"environments": ["lp-sphere"], "algorithms": ["iso", "cma-me"], "seeds": "1,2,3"},
                          "header": {"title": "Linear projection", "date": "d", "command": "c"}})
        text = regenerate(out)
        self.assertTrue(text.startswith("# Linear projection\n"))
        # Nearest-rank quartiles: of (100, 200, 300) 200 (100-300); of (400, 500) 400 (400-500).
        self.assertIn("| MAPE-Iso | 3 | 40 | 200 (100-300) | 50.00 (25.00-75.00) | 2.50 (2.50-2.50) |", text)
        self.assertIn("| cma-me | 2 | 40 | 400 (400-500) | 100.00 (100.00-125.00) | 2.50 (2.50-2.50) |", text)
        self.assertIn("| cma-me | 2/2 | 40 | 9 (9-9) |", text)  # the coverage table names it as the figures do
        self.assertIn("![QD metrics lp-sphere](figures/qd-lp-sphere.png)", text)
        self.assertTrue((out / "figures" / "qd-lp-sphere.png").exists())


class Parts(unittest.TestCase):
    def test_study_round_trip(self):
        out = fixtures.tmpdir(self)
        record = {"selection": {"environments": ["a"], "seeds": "1", "set": ["x.y=\"z\""]},
                  "header": {"command": "it's \"quoted\"", "notes": [], "preface": "line 1\nline 2 \"\"\" end\n"},
                  "addendum": [{"after": "## Cost", "text": "t\n"}]}
        study.write(out, record)
        self.assertEqual(study.read(out), record)

    def test_commands_show_no_paths_of_this_machine(self):
        out = fixtures.tmpdir(self) / "report"
        shown = commands.Shown(out)
        line = shown([commands.BASE / "share" / "qdreport", "-o", out / "runs", "/opt/elsewhere/qdrun"])
        self.assertEqual(line, "share/qdreport -o REPORT_DIR/runs .../qdrun")

    def test_estimate_and_invocations(self):
        out = fixtures.tmpdir(self)
        (out / "estimate.txt").write_text(
            "# header\nestimate (...):\n  striker-iso/seed-1   0.25 core-h: 22000 evaluations ...\n"
            "  striker-poms/seed-1   0.30 core-h: 22000 evaluations 0.20 h, training 0.10 h (loop 0: ...)\n"
            "sweep: estimated 0.50 core-hours (episodes 0.5); on this machine, 2 at a time on 2 cores: about 0.25 hours\n")
        per_run, total = sweep.read_estimate(out / "estimate.txt")
        self.assertEqual(per_run, {"striker-iso/seed-1": {"core_h": 0.25, "episodes_h": 0.25},
                                   "striker-poms/seed-1": {"core_h": 0.30, "episodes_h": 0.20}})
        self.assertEqual(total, {"core_h": 0.5, "jobs": 2, "cores": 2, "wall_h": 0.25, "sweeps": 1})
        # A study made by two sweeps of different runs keeps both dry-runs: the totals add up.
        with open(out / "estimate.txt", "a") as f:
            f.write("\n# the second sweep\nestimate (...):\n  striker-iso/seed-2   0.20 core-h: 22000 evaluations ...\n"
                    "sweep: estimated 0.20 core-hours (episodes 0.2); on this machine, 1 at a time on 2 cores: about "
                    "0.20 hours\n")
        per_run, total = sweep.read_estimate(out / "estimate.txt")
        self.assertEqual(per_run["striker-iso/seed-2"], {"core_h": 0.20, "episodes_h": 0.20})
        self.assertEqual(len(per_run), 3)
        self.assertAlmostEqual(total["core_h"], 0.70)
        self.assertAlmostEqual(total["wall_h"], 0.45)
        self.assertEqual((total["jobs"], total["cores"], total["sweeps"]), (None, None, 2))
        sweep.log_invocation(out / "invocations.csv", "T1", "", "running", "")
        sweep.log_invocation(out / "invocations.csv", "T1", "12.5", "0", "3 runs: 3 finished, 0 failed")
        self.assertEqual(sweep.read_invocations(out / "invocations.csv"),
                         [{"started_utc": "T1", "wall_seconds": "12.5", "exit_code": "0",
                           "summary": "3 runs: 3 finished; 0 failed"}])

    def test_loop_rates(self):
        run = Run(fixtures.write_run(fixtures.tmpdir(self), metrics=[(0, 20, 5), (1, 30, 8), (1, 40, 9)]))
        s = summarise(run)  # wall seconds 0.1, 0.2, 0.3 at 20, 30, 40 evaluations; no training
        self.assertAlmostEqual(s["loop_rates"][0], 0.1 / 20)
        self.assertAlmostEqual(s["loop_rates"][1], (0.3 - 0.1) / 20)
        self.assertEqual((s["elites"], s["evaluations"], s["status"]), (9, 40, "complete"))


if __name__ == "__main__":
    unittest.main()
