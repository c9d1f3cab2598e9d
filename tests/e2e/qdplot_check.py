#!/usr/bin/python3
"""Checks qdplot's output against the run directories, computing every number again here from the
files (read with the tools' reader): files of every kind exist, PNGs decode to the documented pixel
size, SVGs parse as XML with the documented size, every figure labels its axes and explains its
colours, and the plotted series equal the CSV files."""
import json
import math
import sys
from pathlib import Path

from figure_check import explained, png_size, runs, svg_size

from qdtools.stats import nearest

runs_root, fig = Path(sys.argv[1]), Path(sys.argv[2])
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


# Documented sizes (share/README.md) in inches; qdplot's default dpi is 100.
# Maps by layout: the Striker's 17 x 30 x 30 grid as panels, the Walker's 5 x 100 x 5 x 5 as one very wide
# nested image, the Kicker's 50 x 200 as a wide one.
SIZES = {"coverage": (8, 6), "map-panels": (12, 6.5), "map-very-wide": (14, 4), "map-wide": (12, 4.5),
         "traces": (7, 7), "latents": (11, 5), "losses": (8, 5)}
EXPECTED = {
    "coverage-arm": "coverage", "coverage-striker": "coverage", "coverage-bipedal-kicker": "coverage",
    "coverage-bipedal-walker": "coverage",
    "map-striker-poms": "map-panels", "map-bipedal-kicker-ps-uniform": "map-wide",
    "map-bipedal-walker-mape-iso": "map-very-wide",
    "traces-striker-poms": "traces", "traces-bipedal-kicker-ps-uniform": "traces",
    "traces-bipedal-walker-mape-iso": "traces",
    "latents-striker-poms": "latents", "latents-arm-poms": "latents",
    "losses-striker-poms": "losses", "losses-arm-poms": "losses",
}


for stem, size_kind in EXPECTED.items():
    w, h = SIZES[size_kind]
    try:
        check(png_size(fig / f"{stem}.png") == (round(w * 100), round(h * 100)), f"{stem}.png size")
    except Exception as e:  # noqa: BLE001 -- any failure to read is a test failure
        failures.append(f"{stem}.png: {e}")
    try:
        sw, sh = svg_size(fig / f"{stem}.svg")
        check(math.isclose(sw, w * 72) and math.isclose(sh, h * 72), f"{stem}.svg size")
    except Exception as e:  # noqa: BLE001
        failures.append(f"{stem}.svg: {e}")
# Every figure explains itself: labelled axes and ticks, a legend or a colour bar.
for path in sorted(fig.glob("*.json")):
    if path.name != "qdplot.json":
        failures += explained(json.loads(path.read_text()), path.stem)
manifest = json.loads((fig / "qdplot.json").read_text())
check({f["file"] for f in manifest["files"]} >= {f"{s}.{x}" for s in EXPECTED for x in ("png", "svg")}, "manifest")


rows = runs.read_csv


def run_dirs(name):
    return sorted((runs_root / name).glob("seed-*"))


def cells_of(run):
    return runs.read_toml(run / "provenance.toml")["cells"]


# Coverage: the median and quartiles over seeds at every evaluation count, in percent of all cells.
cov = json.loads((fig / "coverage-arm.json").read_text())
for alg, name in (("MAPE-Iso", "smoke-iso"), ("PoMS", "smoke-poms")):
    entry = cov["algorithms"][alg]
    dirs = run_dirs(name)
    check(entry["seeds"] == [1, 2, 3], f"{alg} seeds {entry['seeds']}")
    series = []
    for d in dirs:
        m = rows(d / "metrics.csv")
        series.append({int(r["evaluations"]): 100.0 * int(r["elites"]) / cells_of(d) for r in m})
        check(math.isclose(100 * float(m[-1]["coverage"]), series[-1][int(m[-1]["evaluations"])], rel_tol=1e-4),
              "coverage column vs elites")
    xs = sorted(series[0])
    check(entry["evaluations"] == xs, f"{alg} evaluation grid")
    for i, x in enumerate(xs):
        vals = [s[x] for s in series]
        for key, q in (("median", 50), ("q25", 25), ("q75", 75)):
            check(math.isclose(entry[key][i], nearest(vals, q), abs_tol=1e-9), f"{alg} {key} at {x}")
    loops = {}
    for r in rows(dirs[0] / "metrics.csv"):
        loops[int(r["loop"])] = int(r["evaluations"])
    check(entry["loop_end_evaluations"] == sorted(loops.values()), f"{alg} loop boundaries")
check("mixing_ratio" in cov["algorithms"]["PoMS"], "PoMS mixing ratio panel")

# Maps: every elite of the archive is a filled cell (map_check.py checks every cell's pixel).
for stem, name in (("map-striker-poms", "striker-poms"), ("map-bipedal-kicker-ps-uniform", "bipedal-kicker-ps-uniform"),
                   ("map-bipedal-walker-mape-iso", "bipedal-walker-iso")):
    data = json.loads((fig / f"{stem}.json").read_text())
    cells = [int(r["index"]) for r in rows(run_dirs(name)[0] / "archive.csv")]
    check(data["elites"] == len(cells) and data["filled"] == len(cells), f"{stem}: {data['filled']} vs {len(cells)}")
    if "per_panel" in data:
        check(data["per_panel"] == [sum(1 for c in cells if c // 900 == g) for g in range(17)], f"{stem} panels")

# The Striker names its wall classes in grid.toml: the panels are titled with them.
titles = [a["title"] for a in json.loads((fig / "map-striker-poms.json").read_text())["figure"]["axes"]]
check(titles[0].startswith("walls none (") and titles[5].startswith("walls S-E (") and titles[16].startswith(
    "walls W-N ("), f"striker panel titles {titles[:6]}")

# Trajectories: one path per elite, and every replay lands in its stored cell.
for stem, name in (("traces-striker-poms", "striker-poms"), ("traces-bipedal-kicker-ps-uniform",
                   "bipedal-kicker-ps-uniform"), ("traces-bipedal-walker-mape-iso", "bipedal-walker-iso")):
    data = json.loads((fig / f"{stem}.json").read_text())
    n = len(rows(run_dirs(name)[0] / "archive.csv"))
    check(data["elites"] == n and data["replayed_as_stored"] == n, f"{stem}: {data['elites']} paths, {n} elites")

# Latents: the two dimensions of highest variance of the dataset's codes, one point per dataset entry.
for stem, name in (("latents-striker-poms", "striker-poms"), ("latents-arm-poms", "smoke-poms")):
    data = json.loads((fig / f"{stem}.json").read_text())
    table = rows(data["source"])
    zcols = [k for k in table[0] if k.startswith("z_")]
    def variance(k):
        v = [float(r[k]) for r in table]
        mean = sum(v) / len(v)
        return sum((a - mean) ** 2 for a in v) / len(v)
    ranked = sorted(zcols, key=lambda k: -variance(k))
    check(data["dimensions"] == ranked[:2], f"{stem} dimensions {data['dimensions']} vs {ranked[:2]}")
    check(data["entries"] == len(table), f"{stem} entries")

# Losses: every epoch of every loop of losses.csv.
for stem, name in (("losses-striker-poms", "striker-poms"),):
    data = json.loads((fig / f"{stem}.json").read_text())
    ls = rows(run_dirs(name)[0] / "losses.csv")
    for loop, entry in data["loops"].items():
        mine = [r["train_loss"] for r in ls if int(r["loop"]) == int(loop)]
        check(entry["train_loss"] == mine, f"{stem} loop {loop} train losses")

# Epoch caps: every figure of a capped autoencoder run says so (the fixture caps smoke at 30, the
# paper's runs at 20 epochs per loop); runs without an autoencoder have none.
check(cov["algorithms"]["PoMS"]["epoch_caps"] == [30] and cov["algorithms"]["MAPE-Iso"]["epoch_caps"] == [],
      f"coverage-arm epoch caps {cov['algorithms']['PoMS']['epoch_caps']}")
for stem, cap in (("map-striker-poms", 20), ("traces-striker-poms", 20), ("latents-striker-poms", 20),
                  ("losses-striker-poms", 20), ("losses-arm-poms", 30), ("map-bipedal-walker-mape-iso", None)):
    got = json.loads((fig / f"{stem}.json").read_text())["epoch_cap"]
    check(got == cap, f"{stem}: epoch cap {got}, expected {cap}")
by_file = {f["file"]: f for f in manifest["files"]}
check(by_file["map-striker-poms.png"]["epoch_caps"] == [20] and by_file["coverage-striker.png"]["epoch_caps"] == [20]
      and by_file["map-bipedal-walker-mape-iso.png"]["epoch_caps"] == [], "manifest epoch caps")
check(by_file["map-striker-poms.png"]["runs"] == [str(run_dirs("striker-poms")[0])], "manifest runs")

# The Walker's coverage both ways: 12 500 cells and the reference's index space of 50 000.
walker = json.loads((fig / "coverage-bipedal-walker.json").read_text())["algorithms"]["MAPE-Iso"]
n = len(rows(run_dirs("bipedal-walker-iso")[0] / "archive.csv"))
check((walker["cells"], walker["index_space"], walker["final_median_elites"]) == (12500, 50000, n),
      f"walker coverage: {walker['cells']}, {walker['index_space']}, {walker['final_median_elites']} (elites {n})")
check(json.loads((fig / "map-bipedal-walker-mape-iso.json").read_text())["index_space"] == 50000, "walker map")
check(json.loads((fig / "coverage-striker.json").read_text())["algorithms"]["PoMS"]["index_space"] is None,
      "striker has no second denominator")

if failures:
    print("qdplot check FAILED:\n  " + "\n  ".join(failures))
    sys.exit(1)
print(f"qdplot check ok: {len(EXPECTED)} figures x 2 formats")
