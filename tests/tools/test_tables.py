"""qdtools.tables and the map layout: names and orientations come from share/'s tables."""
import unittest

import fixtures

from qdtools import tables
from qdtools.figures import maps
from qdtools.runs import Grid


class Variants(unittest.TestCase):
    def test_environment_variant_names(self):
        envs = tables.environments()
        self.assertEqual(envs.variant({"type": "striker", "mix_scale": False}), "striker")
        self.assertEqual(envs.variant({"type": "striker", "mix_scale": True, "mix_scale_elements": "paper"}),
                         "striker-mix-scale")
        self.assertEqual(envs.variant({"type": "striker", "mix_scale": True, "mix_scale_elements": "companion"}),
                         "striker-mix-scale-companion")
        self.assertEqual(envs.variant({"type": "striker", "mix_scale": True}), "striker-mix-scale-companion")
        self.assertEqual(envs.variant({"type": "bipedal-kicker", "normalised": True}), "bipedal-kicker")
        self.assertEqual(envs.variant({"type": "bipedal-kicker"}), "bipedal-kicker-world-units")
        self.assertEqual(envs.variant({"type": "bipedal-walker"}), "bipedal-walker")
        self.assertEqual(envs.variant({"type": "point-mass", "mix_scale": True}), "point-mass-mix-scale-companion")

    def test_experiment_variants_are_the_directories_of_the_paper(self):
        self.assertEqual(tables.experiment_variants(fixtures.SOURCE / "experiments"),
                         ["bipedal-kicker", "bipedal-kicker-mix-scale", "bipedal-walker", "bipedal-walker-mix-scale",
                          "striker", "striker-mix-scale"])
        # The reference set is a directory of variants too (qdreport --experiments experiments/reference).
        self.assertEqual(tables.experiment_variants(fixtures.SOURCE / "experiments" / "reference"),
                         ["bipedal-kicker", "bipedal-walker", "striker"])

    def test_algorithms(self):
        algs = tables.algorithms()
        self.assertEqual(algs.name_of("autoencoder", "poms"), "PoMS")
        self.assertIsNone(algs.name_of("none", "decaying-iso"))
        self.assertTrue(algs.is_sampler("ps-glorot") and not algs.is_sampler("iso"))
        self.assertEqual(algs.index_space({"descriptor": {"type": "walker-gait", "contact_bins": "reference"}})[0],
                         50000)
        self.assertEqual(algs.index_space({"descriptor": {"type": "walker-gait", "contact_bins": "even"}}),
                         (None, None))
        self.assertEqual(algs.rank("decaying-iso"), (len(algs.order), "decaying-iso"))

    def test_no_two_curves_of_a_figure_look_alike(self):
        algs = tables.algorithms()
        names = ["PoMS", "PoMS CVT", "MAPE-Iso CVT", "cma-me", "my-op"] + [f"op-{k}" for k in range(5)]
        styles = algs.styles(names)
        self.assertEqual(len(set(styles.values())), len(names), styles)
        poms = tuple(algs.by_name["PoMS"][k] for k in ("colour", "marker"))
        self.assertEqual((styles["PoMS"], styles["PoMS CVT"]), (poms + ("-",), poms + ("--",)))
        self.assertEqual(styles["cma-me"], ("black", ".", "-"))  # the first unknown, in legend order
        self.assertTrue(algs.plots_mixing_ratio("PoMS CVT") and not algs.plots_mixing_ratio("MAPE-Iso CVT"))
        self.assertEqual(sorted(names, key=algs.rank)[:3], ["PoMS", "PoMS CVT", "MAPE-Iso CVT"])


def grid(shape, names=None):
    names = names or [f"d{k}" for k in range(len(shape))]
    return Grid(1, list(shape), names, [0.0] * len(shape), [1.0] * len(shape))


class Layout(unittest.TestCase):
    def test_dimension_zero_goes_right(self):
        self.assertEqual(maps.layout(grid([20, 30])), {"layout": "nested", "panel": None, "horizontal": [0],
                                                       "vertical": [1]})
        self.assertEqual(maps.layout(grid([7]))["horizontal"], [0])
        self.assertEqual(maps.layout(grid([4, 5, 6, 7])), {"layout": "nested", "panel": None, "horizontal": [0, 2],
                                                           "vertical": [1, 3]})
        self.assertEqual(maps.layout(grid([3, 8, 24])), {"layout": "panels", "panel": 0, "horizontal": [1],
                                                         "vertical": [2]})
        self.assertEqual(maps.layout(grid([40, 8, 24]))["layout"], "nested")

    def test_the_papers_descriptors_are_drawn_as_the_reference_draws_them(self):
        striker = grid([17, 30, 30], ["walls", "y", "x"])
        self.assertEqual(maps.layout(striker, "striker-contacts"), {"layout": "panels", "panel": 0,
                                                                     "horizontal": [2], "vertical": [1]})
        walker = grid([5, 100, 5, 5], ["mean_hull_y", "final_hull_x_fraction", "left_contact_fraction",
                                       "right_contact_fraction"])
        self.assertEqual(maps.layout(walker, "walker-gait")["horizontal"], [1, 3])
        kicker = grid([50, 200], ["max_ball_y", "final_ball_x"])
        self.assertEqual(maps.layout(kicker, "kicker-ball")["horizontal"], [1])
        # A grid the table's names do not fit (a changed descriptor) falls back to the rule.
        self.assertEqual(maps.layout(grid([50, 200]), "kicker-ball")["horizontal"], [0])

    def test_position_is_mixed_radix_outer_first(self):
        g = grid([4, 5, 6, 7])
        cell = ((2 * 5 + 3) * 6 + 4) * 7 + 5
        bins = g.unravel([cell])
        self.assertEqual(maps.position(bins, g.shape, [0, 2]).tolist(), [2 * 6 + 4])
        self.assertEqual(maps.position(bins, g.shape, [1, 3]).tolist(), [3 * 7 + 5])


class PaperCurves(unittest.TestCase):
    """share/paper-curves.csv read back: known points, linear between them, None outside; every
    figure environments.toml names and every algorithm in it exists in the tables."""

    def test_points_and_interpolation(self):
        share = fixtures.tmpdir(self)
        (share / "paper-curves.csv").write_text("figure,algorithm,quantity,evaluations,value,visibility\n"
                                                "F,A,coverage_percent,10000,1.0,visible\n"
                                                "F,A,coverage_percent,20000,3.0,hidden\n")
        self.assertEqual(tables.paper_value("F", "A", 10000, share=share), 1.0)
        self.assertEqual(tables.paper_value("F", "A", 15000, share=share), 2.0)
        self.assertIsNone(tables.paper_value("F", "A", 30000, share=share))
        self.assertIsNone(tables.paper_value("F", "B", 10000, share=share))

    def test_the_installed_table_names_known_figures_and_algorithms(self):
        curves = tables.paper_curves()
        figures = {k[0] for k in curves}
        self.assertTrue({f["figure"] for f in tables.environments().paper_figures.values()} <= figures)
        self.assertEqual({k[1] for k in curves}, set(tables.algorithms().order))
        # The Walker figure's PoMS curve, read at the published 100 000 evaluations.
        self.assertAlmostEqual(tables.paper_value("BipedalWalker", "PoMS", 100000), 3.489)


if __name__ == "__main__":
    unittest.main()
