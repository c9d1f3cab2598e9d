"""qdreport's parts: summary (one run's numbers), sweep (the qdrun sweep, its estimate and
invocations), sections (REPORT.md), study (study.toml), commands (paths as a report shows them)."""
