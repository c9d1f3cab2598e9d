"""qdplot's figures for a task the tools know nothing of (an environment of one's own): maps with
dimension 0 to the right and square cells, a fitness map when fitness varies, and every figure
with labelled axes, labelled ticks and a legend or colour bar; the QD metrics' curves (their
numbers parsed back from the figure's data) and a CVT archive's Voronoi map (its pixels checked
against a brute-force nearest centroid)."""
import contextlib
import io
import json
import math
import unittest

import fixtures
import matplotlib
import numpy as np
from PIL import Image

from qdtools import plot_cli, runs
from qdtools.figures import latents, voronoi

GRID = ([4, 3], ["x", "y"], [0.0, 0.0], [2.0, 1.5])  # cells of 0.5 x 0.5: square


def plot(test, archive, kinds="coverage,maps", **run):
    root = fixtures.tmpdir(test)
    fixtures.write_run(root / "runs", grid=GRID, archive=archive, experiment_file="/x/decaying-iso.toml", **run)
    with contextlib.redirect_stdout(io.StringIO()) as said:
        plot_cli.plot([root / "runs"], root / "figures", kinds.split(","), formats=("png",), dump=True)
    return root / "figures", said.getvalue()


def dump(figures, stem):
    return json.loads((figures / f"{stem}.json").read_text())


class Figures(unittest.TestCase):
    def test_every_figure_explains_itself(self):
        # cells: 2 * 3 + 1 = 7 is x bin 2, y bin 1; 9 is x bin 3, y bin 0.
        figures, _ = plot(self, [(7, 1.0, 1.2, 0.7), (9, 3.0, 1.8, 0.1), (0, 2.0, 0.1, 0.1)])
        for stem in ("coverage-point-mass", "map-point-mass-decaying-iso", "map-point-mass-decaying-iso-fitness"):
            fig = dump(figures, stem)["figure"]
            self.assertTrue(fig["legends"] or fig["colorbars"], stem)
            for ax in fig["axes"]:
                self.assertTrue(ax["xlabel"] and ax["ylabel"], (stem, ax))
                self.assertGreaterEqual(min(ax["xticks"], ax["yticks"]), 2, (stem, ax))
        cov = dump(figures, "coverage-point-mass")["figure"]
        self.assertTrue(any(t.startswith("decaying-iso (1 seed): 12 cells") for t in cov["legends"]), cov)
        occupancy = dump(figures, "map-point-mass-decaying-iso")
        self.assertEqual(occupancy["figure"]["legends"], ["elite (3)", "empty cell (9)"])
        fitness = dump(figures, "map-point-mass-decaying-iso-fitness")
        self.assertEqual((fitness["vmin"], fitness["vmax"]), (1.0, 3.0))
        self.assertEqual(fitness["figure"]["colorbars"], ["fitness (archive.csv objective)"])

    def test_seeds_of_unequal_length_are_dotted_where_fewer_seeds_reach(self):
        # Seeds 1 and 2 to 40 evaluations, seed 3 on to 60 (a study still running): the legend gives
        # the median where all three have run (nearest rule: of 8, 9, 10 cells, 9), the curve goes on
        # dotted over one seed.
        root = fixtures.tmpdir(self)
        for seed, rows in ((1, [(0, 20, 5), (1, 40, 8)]), (2, [(0, 20, 6), (1, 40, 9)]),
                           (3, [(0, 20, 4), (1, 40, 10), (2, 60, 30)])):
            fixtures.write_run(root / "runs", seed=seed, grid=GRID, metrics=rows, experiment_file="/x/decaying-iso.toml")
        with contextlib.redirect_stdout(io.StringIO()):
            plot_cli.plot([root / "runs"], root / "figures", ["coverage"], formats=("png",), dump=True)
        data = dump(root / "figures", "coverage-point-mass")
        self.assertIn("decaying-iso (3 seeds; 1 past 40, dotted): 9 cells, 75.00 %", data["figure"]["legends"])
        entry = data["algorithms"]["decaying-iso"]
        self.assertEqual(entry["runs_reaching"], [3, 3, 1])
        self.assertIn("dotted: fewer seeds", data["figure"]["axes"][0]["title"])

    def test_dimension_zero_to_the_right_in_square_cells(self):
        figures, _ = plot(self, [(7, 1.0, 1.2, 0.7)], kinds="maps")
        m = dump(figures, "map-point-mass-decaying-iso")
        self.assertEqual((m["horizontal"], m["vertical"]), ([0], [1]))
        self.assertEqual(m["axes"][0]["cols"], 4)
        self.assertEqual(m["axes"][0]["rows"], 3)
        x0, y0, x1, y1 = m["axes"][0]["bbox"]
        self.assertAlmostEqual((x1 - x0) / (y1 - y0), 4 / 3, delta=0.02)
        self.assertIn("x (4 bins over [0, 2])", m["figure"]["axes"][0]["xlabel"])

    def test_no_fitness_map_when_fitness_is_constant(self):
        figures, said = plot(self, [(7, 0.0, 1.2, 0.7), (9, 0.0, 1.8, 0.1)], kinds="maps")
        self.assertFalse((figures / "map-point-mass-decaying-iso-fitness.png").exists())
        self.assertIn("no fitness map", said)
        self.assertIn("every elite has the same fitness", said)

    def test_a_cvt_archive_gets_coverage_and_voronoi_maps(self):
        root = fixtures.tmpdir(self)
        run = fixtures.write_run(root / "runs", centroids=(["x", "y"], [(0.0, 0.0), (1.0, 0.5), (0.5, 1.0)]),
                                 archive=[(0, 1.0, 0.1, 0.1), (2, 2.0, 0.6, 0.9)], rep="autoencoder", mutator="poms",
                                 metrics=[(0, 10, 1), (1, 20, 2)])
        with contextlib.redirect_stdout(io.StringIO()) as said:
            plot_cli.plot([root / "runs"], root / "figures", ["coverage", "maps"], formats=("png",), dump=True)
        self.assertEqual(sorted(p.name for p in (root / "figures").glob("*.png")),
                         ["coverage-point-mass.png", "map-point-mass-poms-cvt-fitness.png", "map-point-mass-poms-cvt.png"])
        self.assertEqual(dump(root / "figures", "map-point-mass-poms-cvt")["kind"], "cvt")
        self.assertNotIn("no map", said.getvalue())
        cov = dump(root / "figures", "coverage-point-mass")["figure"]
        self.assertTrue(any(t == "PoMS CVT (1 seed): 2 cells, 66.67 %" for t in cov["legends"]), cov)
        # Latent codes are coloured by the coordinates of their cell's centroid.
        names, values = zip(*latents.colourings(runs.read_grid(run), np.array([2, 0, 2])))
        self.assertEqual(names, ("x of the cell's centroid", "y of the cell's centroid"))
        self.assertEqual([v.tolist() for v in values], [[0.5, 0.0, 0.5], [1.0, 0.0, 1.0]])

    def test_trajectories_of_an_unknown_task_from_its_trace_columns(self):
        # qdrun --replay's output is written beforehand: qdplot replays only when it is older than
        # the archive, so /bin/true stands in for qdrun.
        for rows_per_path, header, said_expected in (
                (3, "main_0,main_1", "one path per elite (2), coloured by its final main_0"),
                (1, "main_0,main_1", "one point per elite whose trace is one row (2), coloured by its main_0"),
                (2, "", "environment 'point-mass' records no rows in its trace's main table (Trace::main)")):
            root = fixtures.tmpdir(self)
            fixtures.write_run(root / "runs", grid=GRID, archive=[(7, 1.0, 1.2, 0.7), (9, 3.0, 1.8, 0.1)],
                               experiment_file="/x/decaying-iso.toml")
            data = root / "figures" / "data" / "traces-point-mass-decaying-iso-seed-1.csv"
            data.parent.mkdir(parents=True)
            data.write_text("cell,landed,status,row" + ("," + header if header else "") + "\n" + "".join(
                f"{cell},{cell},ok,{k}" + (f",{0.1 * k + cell},{0.2 * k}" if header else "") + "\n"
                for cell in (7, 9) for k in range(rows_per_path)))
            with contextlib.redirect_stdout(io.StringIO()) as said:
                plot_cli.plot([root / "runs"], root / "figures", ["traces"], formats=("png",), dump=True,
                              qdrun="/bin/true")
            if not header:
                self.assertIn(said_expected, said.getvalue())
                self.assertFalse((root / "figures" / "traces-point-mass-decaying-iso.png").exists())
                continue
            fig = dump(root / "figures", "traces-point-mass-decaying-iso")["figure"]
            self.assertEqual(fig["legends"], [said_expected])
            self.assertEqual(fig["colorbars"], ["final main_0" if rows_per_path > 1 else "main_0"])
            self.assertEqual(fig["axes"][0]["xlabel"], "main_0 (column 1 of the trace's main table)")
            self.assertEqual(fig["axes"][0]["ylabel"], "main_1 (column 2 of the trace's main table)")
            self.assertGreaterEqual(min(fig["axes"][0]["xticks"], fig["axes"][0]["yticks"]), 2)

    def test_trajectories_say_how_many_elites_replay_into_their_own_cell(self):
        # An environment with persistent worlds stores elites where a fresh world may not put them.
        root = fixtures.tmpdir(self)
        fixtures.write_run(root / "runs", grid=GRID, archive=[(7, 1.0, 1.2, 0.7), (9, 3.0, 1.8, 0.1)],
                           experiment_file="/x/decaying-iso.toml")
        data = root / "figures" / "data" / "traces-point-mass-decaying-iso-seed-1.csv"
        data.parent.mkdir(parents=True)
        data.write_text("cell,landed,status,row,main_0,main_1\n7,7,ok,0,0.1,0.2\n7,7,ok,1,0.2,0.3\n"
                        "9,4,ok,0,0.5,0.1\n9,4,ok,1,0.6,0.2\n")
        with contextlib.redirect_stdout(io.StringIO()) as said:
            plot_cli.plot([root / "runs"], root / "figures", ["traces"], formats=("png",), dump=True, qdrun="/bin/true")
        moved = "in a fresh world 1 of 2 elites replay into their own cell: these are the replays' paths"
        self.assertIn(moved, said.getvalue())
        fig = dump(root / "figures", "traces-point-mass-decaying-iso")["figure"]
        self.assertEqual(fig["legends"], ["one path per elite (2), coloured by its final main_0", moved])

    def test_loss_curves_label_several_ticks_whatever_their_range(self):
        for low, high in ((100.0, 120.0), (80.0, 600.0), (1e-3, 50.0)):
            root = fixtures.tmpdir(self)
            run = fixtures.write_run(root / "runs", rep="autoencoder", mutator="my-op")
            steps = [low + (high - low) * k / 9 for k in range(10)]
            (run / "losses.csv").write_text("loop,epoch,train_loss,test_loss\n" + "".join(
                f"{k // 5},{k % 5},{v},{v * 1.01 if k >= 5 else ''}\n" for k, v in enumerate(reversed(steps))))
            with contextlib.redirect_stdout(io.StringIO()):
                plot_cli.plot([root / "runs"], root / "figures", ["losses"], formats=("png",), dump=True)
            fig = dump(root / "figures", "losses-point-mass-my-env-decaying")["figure"]
            self.assertGreaterEqual(fig["axes"][0]["yticks"], 3, (low, high, fig))
            self.assertEqual(fig["legends"], ["train loss (solid)", "test loss (dashed)"])
            self.assertEqual(fig["colorbars"], ["loop"])


QD_ROWS = [(0, 20, 5), (1, 30, 8), (1, 40, 9), (2, 50, 12)]


def qd_runs(root, per_seed):
    """Runs of one task with fitness, seeds 1.. with the given QD scores per row (max and mean fitness
    derived from them)."""
    for seed, scores in enumerate(per_seed, 1):
        fixtures.write_run(root / "runs", seed=seed, experiment_file="/x/decaying-iso.toml", metrics=QD_ROWS,
                           qd=[(q, q / 10 + 1, q / 20) for q in scores])


class QdFigure(unittest.TestCase):
    def test_qd_curves_are_the_seeds_median_and_quartiles(self):
        root = fixtures.tmpdir(self)
        qd_runs(root, [[10, 20, 25, 40], [12, 18, 30, 44], [11, 22, 21, 38]])
        with contextlib.redirect_stdout(io.StringIO()):
            plot_cli.plot([root / "runs"], root / "figures", ["qd"], formats=("png",), dump=True)
        qd = dump(root / "figures", "qd-point-mass")
        curve = qd["algorithms"]["decaying-iso"]
        self.assertEqual(curve["seeds"], [1, 2, 3])
        self.assertEqual(curve["qd_score"]["evaluations"], [20, 30, 40, 50])
        self.assertEqual(curve["qd_score"]["median"], [11, 20, 25, 40])   # the middle of 3 seeds at each row
        self.assertEqual(curve["qd_score"]["q25"], [10, 18, 21, 38])
        self.assertEqual(curve["qd_score"]["q75"], [12, 22, 30, 44])
        self.assertEqual(curve["max_fitness"]["median"], [2.1, 3.0, 3.5, 5.0])
        self.assertEqual(curve["mean_fitness"]["final_median"], 2.0)
        self.assertEqual(curve["loop_end_evaluations"], [20, 40, 50])
        fig = qd["figure"]
        self.assertIn("decaying-iso (3 seeds): QD score 40, max fitness 5, mean 2", fig["legends"])
        self.assertEqual([a["ylabel"] for a in fig["axes"]],
                         ["QD score\n(sum of fitness - bound)", "max fitness", "mean fitness"])
        self.assertEqual(fig["axes"][-1]["xlabel"], "evaluations")

    def test_no_qd_figure_for_a_task_without_fitness(self):
        figures, said = plot(self, [(7, 1.0, 1.2, 0.7)], kinds="qd")
        self.assertFalse((figures / "qd-point-mass.png").exists())
        self.assertIn("no QD figure for point-mass: its task has no fitness", said)


# A CVT archive of 7 cells over [0, 4] x [0, 2]; cells 1, 3, 4 and 6 hold elites.
CENTROIDS = [(0.3, 0.4), (1.1, 1.6), (1.9, 0.7), (2.6, 1.5), (3.3, 0.3), (3.6, 1.7), (2.2, 1.9)]
CVT_ARCHIVE = [(1, 3.0, 1.0, 1.5), (3, 5.0, 2.5, 1.4), (4, 1.0, 3.2, 0.4), (6, 4.0, 2.1, 1.8)]


class VoronoiMap(unittest.TestCase):
    def test_nearest_centroid_is_the_brute_force_one(self):
        rng = np.random.default_rng(5)
        centroids = rng.uniform(-1, 3, size=(300, 2))
        points = rng.uniform(-1.5, 3.5, size=(5000, 2))
        brute = np.argmin(((points[:, None, :] - centroids[None]) ** 2).sum(axis=2), axis=1)
        tiles = (np.floor(points[:, 0] * 3).astype(int) + 10) * 100 + np.floor(points[:, 1] * 3).astype(int) + 10
        np.testing.assert_array_equal(voronoi.nearest_centroid(points, centroids, tiles), brute)
        np.testing.assert_array_equal(voronoi.nearest_centroid(points, centroids), brute)

    def test_every_cell_has_the_colour_of_its_elite(self):
        root = fixtures.tmpdir(self)
        fixtures.write_run(root / "runs", mutator="iso", archive=CVT_ARCHIVE,
                           centroids=(["x", "y"], CENTROIDS, [0.0, 0.0], [4.0, 2.0]))
        with contextlib.redirect_stdout(io.StringIO()):
            plot_cli.plot([root / "runs"], root / "figures", ["maps"], formats=("png",), dump=True)
        centroids = np.array(CENTROIDS)
        fitness = {c: f for c, f, *_ in CVT_ARCHIVE}
        viridis = matplotlib.colormaps["viridis"]
        for stem, colour in (("map-point-mass-mape-iso-cvt", lambda c: matplotlib.colors.to_rgb("tab:blue")),
                             ("map-point-mass-mape-iso-cvt-fitness", lambda c: viridis((fitness[c] - 1.0) / 4.0)[:3])):
            m = dump(root / "figures", stem)
            self.assertEqual((m["kind"], m["elites"], m["cells"]), ("cvt", 4, 7))
            self.assertEqual(m["figure"]["axes"][0]["xlabel"], "x ([0, 4])")
            image = np.asarray(Image.open(root / "figures" / f"{stem}.png").convert("RGB"), dtype=float) / 255
            x0, y0, x1, y1 = m["axes"][0]["bbox"]
            self.assertAlmostEqual((x1 - x0) / (y1 - y0), 2.0, delta=0.02)  # to scale: [0, 4] x [0, 2]
            checked = 0
            for px in np.arange(math.ceil(x0) + 2, int(x1) - 2, 3):
                for py in np.arange(math.ceil(y0) + 2, int(y1) - 2, 3):
                    point = np.array([(px + 0.5 - x0) / (x1 - x0) * 4, (py + 0.5 - y0) / (y1 - y0) * 2])
                    d = np.sqrt(((centroids - point) ** 2).sum(axis=1))
                    first, second = np.sort(d)[:2]
                    if second - first < 3 * 4 / (x1 - x0):  # within a few pixels of a border
                        continue
                    cell = int(np.argmin(d))
                    want = colour(cell) if cell in fitness else (1.0, 1.0, 1.0)
                    got = image[image.shape[0] - 1 - py, px]
                    np.testing.assert_allclose(got, want, atol=2 / 255, err_msg=f"{stem} pixel {px},{py} cell {cell}")
                    checked += 1
            self.assertGreater(checked, 2000)


if __name__ == "__main__":
    unittest.main()
