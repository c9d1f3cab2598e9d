"""qdtools.stats: percentiles as numpy's 'nearest' rule, the coverage step function, moving means."""
import math
import unittest

import fixtures
import numpy as np

from qdtools import runs, stats


class Nearest(unittest.TestCase):
    def test_equals_numpys_nearest_rule(self):
        rng = np.random.default_rng(3)
        for n in range(1, 12):
            values = rng.integers(0, 50, n).tolist()
            for q in (0, 25, 50, 75, 100, 37.5):
                self.assertEqual(stats.nearest(values, q), np.percentile(values, q, method="nearest"), (values, q))

    def test_halves_round_to_even_rank(self):
        # 4 values: the median's rank is 1.5, which rounds to 2 (numpy's 'nearest'), not 1.
        self.assertEqual(stats.nearest([10, 20, 30, 40], 50), 30)
        self.assertEqual(stats.nearest([10, 20, 30, 40, 50, 60], 50), 30)  # rank 2.5 -> 2
        self.assertTrue(math.isnan(stats.nearest([], 50)))

    def test_percentile_per_column_skips_nan(self):
        ys = [[1.0, 5.0, math.nan], [2.0, math.nan, math.nan], [3.0, 7.0, math.nan]]
        got = stats.nearest_percentile(ys, 50)
        self.assertEqual(got[0], 2.0)
        self.assertEqual(got[1], 5.0)  # [5, 7]: rank 0.5 rounds to even, 0
        self.assertTrue(math.isnan(got[2]))


class Coverage(unittest.TestCase):
    def test_step_function_in_percent_and_nan_past_the_end(self):
        root = fixtures.tmpdir(self)
        a = runs.Run(fixtures.write_run(root, seed=1, metrics=[(0, 20, 5), (1, 40, 10)]))
        b = runs.Run(fixtures.write_run(root, seed=2, metrics=[(0, 20, 6), (1, 30, 7), (2, 60, 20)]))
        x, ys = stats.coverage_series([a, b])
        self.assertEqual(x.tolist(), [20, 30, 40, 60])
        self.assertEqual(ys[0][:3].tolist(), [5.0, 5.0, 10.0])  # 100 cells: elites = percent
        self.assertTrue(math.isnan(ys[0][3]))
        self.assertEqual(ys[1].tolist(), [6.0, 7.0, 7.0, 20.0])
        self.assertEqual(stats.loop_ends(b), [20, 30, 60])



class PaperMixingRatio(unittest.TestCase):
    """The mixing ratio as the paper's figures aggregate it, against the same steps written out with
    numpy: each row's value repeated over its batch, loop 0 given the first value, the mean over the
    seeds that reached an evaluation, then a centred window with padded ends (np.convolve 'valid')."""

    def test_per_evaluation_repeats_rows_and_fills_loop_zero(self):
        r = runs.Run(fixtures.write_run(fixtures.tmpdir(self), metrics=[(0, 4, 3), (1, 6, 4, 0.5), (1, 9, 5, 0.25)]))
        self.assertEqual(stats.per_evaluation(r).tolist(), [0.5] * 6 + [0.25] * 3)

    def test_mean_over_seeds_then_centred_window(self):
        root = fixtures.tmpdir(self)
        a = runs.Run(fixtures.write_run(root, seed=1, metrics=[(0, 4, 3), (1, 8, 4, 1.0), (2, 12, 5, 0.0)]))
        b = runs.Run(fixtures.write_run(root, seed=2, metrics=[(0, 4, 3), (1, 8, 4, 0.5)]))  # stopped at 8
        ev, mean, half_band = stats.paper_mixing_ratio([a, b], window=4)
        raw = np.array([0.75] * 8 + [0.0] * 4)  # seeds averaged where both ran, seed 1 alone after
        w = 4
        padded = np.concatenate([np.full(w // 2, raw[0]), raw, np.full(w // 2 - 1, raw[-1])])
        want = np.convolve(padded, np.ones(w) / w, mode="valid")
        self.assertEqual(ev.tolist(), list(range(1, 13)))
        np.testing.assert_allclose(mean, want, rtol=0, atol=1e-12)
        self.assertAlmostEqual(mean[0], 0.75)
        self.assertAlmostEqual(mean[-1], 0.0)
        self.assertAlmostEqual(half_band[0], 0.25)  # std over {1.0, 0.5}, clipped band smoothed alike

    def test_none_without_a_ratio(self):
        r = runs.Run(fixtures.write_run(fixtures.tmpdir(self)))
        self.assertIsNone(stats.paper_mixing_ratio([r]))

if __name__ == "__main__":
    unittest.main()
