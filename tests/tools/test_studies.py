"""Every study of results/ is what its files say: its REPORT.md is the text qdreport --regenerate
writes from the study's runs, study.toml and figures/qdplot.json (after a change to the report's
code, regenerate them: `for d in results/*/study.toml; do share/qdreport --regenerate ${d%/*}; done`),
and every figure it shows is there."""
import re
import unittest

import fixtures

from qdtools import report_cli

RESULTS = fixtures.SOURCE / "results"


class Studies(unittest.TestCase):
    def test_reports_are_regenerated_from_their_files(self):
        studies = sorted(p.parent for p in RESULTS.glob("*/study.toml"))
        self.assertGreaterEqual(len(studies), 4)
        for out in studies:
            with self.subTest(study=out.name):
                text = report_cli.render(out, *report_cli.regenerated(out))
                self.assertEqual(text, (out / "REPORT.md").read_text(), f"{out}: run share/qdreport --regenerate {out}")

    def test_every_figure_shown_is_there(self):
        for report in sorted(RESULTS.glob("*/REPORT.md")):
            targets = re.findall(r"\]\((figures/[^)]+)\)", report.read_text())
            self.assertTrue(any("coverage-" in t for t in targets), f"{report}: no coverage figure")
            for target in targets:
                self.assertTrue((report.parent / target).is_file(), f"{report}: {target}")


if __name__ == "__main__":
    unittest.main()
