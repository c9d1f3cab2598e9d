"""qdtools.runs: the one reader of run directories (qdplot, qdreport, qdresults and the e2e checks)."""
import gzip
import math
import shutil
import unittest

import fixtures

from qdtools import ToolError, runs


class Reading(unittest.TestCase):
    def setUp(self):
        self.root = fixtures.tmpdir(self)

    def test_csv_plain_and_gzip_read_alike(self):
        d = fixtures.write_run(self.root, metrics=[(0, 20, 5, ""), (1, 30, 8, 0.25)])
        plain = runs.read_csv(d / "metrics.csv")
        with open(d / "metrics.csv", "rb") as f, gzip.open(d / "metrics.csv.gz", "wb") as z:
            shutil.copyfileobj(f, z)
        (d / "metrics.csv").unlink()
        packed = runs.read_csv(d / "metrics.csv")  # found as metrics.csv.gz
        self.assertEqual(repr(plain), repr(packed))  # repr: NaN == NaN
        self.assertEqual(plain[1]["mixing_ratio"], 0.25)
        self.assertTrue(math.isnan(plain[0]["mixing_ratio"]))
        self.assertEqual(runs.read_csv(d / "metrics.csv", text=True)[1]["evaluations"], "30")

    def test_leading_columns_only(self):
        d = fixtures.write_run(self.root, archive=[(7, 1.5, 0.1, 0.2), (3, -2.0, 0.3, 0.4)])
        rows = runs.read_csv(d / "archive.csv", columns=["index", "objective"])
        self.assertEqual(rows, [{"index": 7.0, "objective": 1.5}, {"index": 3.0, "objective": -2.0}])
        with self.assertRaisesRegex(ToolError, "no column fitness"):
            runs.read_csv(d / "archive.csv", columns=["fitness"])

    def test_archive_without_parameters(self):
        d = fixtures.write_run(self.root, archive=[(7, 1.5, 0.1, 0.2), (3, -2.0, 0.3, 0.4)])
        a = runs.read_archive(d)
        self.assertEqual(a.cells.tolist(), [7, 3])
        self.assertEqual(a.objective.tolist(), [1.5, -2.0])
        self.assertEqual(a.measures.tolist(), [[0.1, 0.2], [0.3, 0.4]])
        self.assertIsNone(runs.read_archive(fixtures.write_run(self.root, seed=2)))

    def test_grid_with_labels_and_unravel(self):
        d = fixtures.write_run(self.root, grid=([3, 2], ["side", "h"], [0, 0], [3, 1],
                                                [["left", "still", "right"], []]))
        g = runs.read_grid(d)
        self.assertEqual((g.cells, g.shape, g.names), (6, [3, 2], ["side", "h"]))
        self.assertEqual(g.bin_label(0, 2), "right")
        self.assertEqual(g.bin_label(1, 1), "1")
        self.assertEqual([b.tolist() for b in g.unravel([0, 1, 5])], [[0, 0, 2], [0, 1, 1]])

    def test_cvt_grid_and_its_centroids(self):
        points = [(0.0, 0.0), (1.0, 0.5), (0.25, 1.0)]
        d = fixtures.write_run(self.root, centroids=(["x", "y"], points))
        g = runs.read_grid(d)
        self.assertTrue(g.is_cvt)
        self.assertEqual((g.cells, g.shape, g.names, g.lower, g.upper), (3, [3], ["x", "y"], [0, 0], [1, 1]))
        self.assertEqual(g.centroids.tolist(), [list(p) for p in points])
        self.assertFalse(runs.read_grid(fixtures.write_run(self.root, seed=2, grid=([2], ["x"], [0], [1]))).is_cvt)
        with gzip.open(d / "centroids.csv.gz", "wt") as z:  # as a study keeps them
            z.write((d / "centroids.csv").read_text())
        (d / "centroids.csv").unlink()
        self.assertEqual(runs.read_grid(d).centroids.tolist(), [list(p) for p in points])
        (d / "centroids.csv.gz").unlink()
        self.assertIsNone(runs.read_grid(d).centroids)  # no archive either: a study kept neither (--archives maps)
        (d / "archive.csv").write_text("index,objective,measures_0,measures_1\n0,1.0,0.0,0.0\n")
        with self.assertRaisesRegex(ToolError, r"grid.toml: a CVT grid whose centroids \(centroids.csv\) are missing"):
            runs.read_grid(d)
        (d / "centroids.csv").write_text("centroid,x,z\n0,0,0\n1,1,1\n2,0,1\n")
        with self.assertRaisesRegex(ToolError, "centroids.csv: not the 3 centroids of grid.toml's x, y"):
            runs.read_grid(d)
        (d / "centroids.csv").write_text("centroid,x,y\n0,0,0\n1,1,1\n")
        with self.assertRaisesRegex(ToolError, "2 rows"):
            runs.read_grid(d)

    def test_grid_that_contradicts_itself(self):
        d = fixtures.write_run(self.root, grid=([3, 2], ["side", "h"], [0, 0], [3, 1], [["a", "b"], []]))
        with self.assertRaisesRegex(ToolError, "does not match"):
            runs.read_grid(d)


class Runs(unittest.TestCase):
    def setUp(self):
        self.root = fixtures.tmpdir(self)

    def test_algorithm_of_the_table_or_of_the_experiment_file(self):
        paper = runs.Run(fixtures.write_run(self.root, name="a", rep="autoencoder", mutator="poms"))
        self.assertEqual(paper.algorithm, "PoMS")
        mine = runs.Run(fixtures.write_run(self.root, name="b", experiment_file="/x/point-mass/decaying-iso.toml"))
        self.assertEqual(mine.algorithm, "decaying-iso")
        unnamed = runs.Run(fixtures.write_run(self.root, name="c"))
        self.assertEqual(unnamed.algorithm, "c")  # the experiment's name

    def test_a_cvt_archive_is_another_algorithm_than_the_grid(self):
        cvt = (["x", "y"], [(0.0, 0.0), (1.0, 1.0)])
        grid = runs.Run(fixtures.write_run(self.root, name="a", mutator="iso", grid=([2, 2], ["x", "y"], [0, 0], [1, 1])))
        on_cvt = runs.Run(fixtures.write_run(self.root, name="b", mutator="iso", centroids=cvt))
        self.assertEqual((grid.algorithm, on_cvt.algorithm), ("MAPE-Iso", "MAPE-Iso CVT"))
        self.assertEqual(sorted(runs.group([grid, on_cvt])["point-mass"]), ["MAPE-Iso", "MAPE-Iso CVT"])
        mine = runs.Run(fixtures.write_run(self.root, name="c", centroids=cvt, experiment_file="/x/my-cvt.toml"))
        self.assertEqual(mine.algorithm, "my-cvt")  # an unknown pair: its file's name says it all

    def test_find_and_median(self):
        for seed, elites in ((1, 9), (2, 3), (3, 5), (4, 7)):
            fixtures.write_run(self.root, seed=seed, metrics=[(0, 10, elites)])
        found = runs.find_runs([self.root])
        self.assertEqual([r.seed for r in found], [1, 2, 3, 4])
        self.assertEqual(runs.median_run(found).seed, 3)  # 3 5 7 9: the lower median, 5
        empty = self.root / "empty"
        empty.mkdir()
        with self.assertRaisesRegex(ToolError, "holds no run directories"):
            runs.find_runs([empty])

    def test_a_file_that_is_no_run(self):
        with self.assertRaisesRegex(ToolError, "not a run directory"):
            runs.find_runs([self.root / "missing"])


if __name__ == "__main__":
    unittest.main()
