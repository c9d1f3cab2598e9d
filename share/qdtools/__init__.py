"""qdtools: the Python side of qdrun, behind share/qdplot, share/qdreport and share/qdresults.

Debian's python3 with matplotlib and numpy only (scripts/install-deps.sh --plots); no pip. The
package lives beside the scripts (share/qdtools in the source tree, <prefix>/share/qd/qdtools
installed), and the scripts put their own directory first on sys.path.

  tables    share/algorithms.toml and share/environments.toml: names, colours, variants, layouts
  runs      run directories: discovery, config/provenance/grid/metrics/archive (plain or .gz)
  stats     nearest-rank percentiles, moving means, coverage series
  qdrun     finding qdrun, and the files it makes for figures (replays, latent codes)
  figures   one module per figure kind, and the output manifest (figures/qdplot.json)
  report    qdreport: the per-run summaries, the sweep, the report's sections, study.toml
  results   what a study in results/ keeps, and the check that nothing bulky is committed
"""


class ToolError(Exception):
    """A problem the user can fix (a missing file, a bad option): printed as one line, no traceback."""
