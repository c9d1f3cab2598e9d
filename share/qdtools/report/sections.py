"""REPORT.md, section by section. Each section is a function of the Report (below) that returns its
Markdown lines; SECTIONS is the order they appear in. A new section is a function and an entry in
SECTIONS; a new per-run quantity is a field of summary.py and a column here. Text a study adds by
hand ([[addendum]] of study.toml) is appended to the section whose heading it names."""
import collections
import math
from dataclasses import dataclass, field

from .. import stats, tables
from .sweep import read_estimate, read_invocations
from .summary import epochs_text


@dataclass
class Report:
    out: object                 # the report directory (Path)
    envs: list                  # environment variants, in order
    algs: list                  # experiment stems of algorithms, in order
    runs: dict                  # (env, alg) -> [summary], every run of the selection found
    figures: list               # qdplot.json entries
    header: dict                # study.toml [header]: date, qdrun, machine, commands, notes, ...
    selection: dict             # study.toml [selection]
    addenda: list = field(default_factory=list)

    @property
    def every_run(self):
        return [s for infos in self.runs.values() for s in infos]

    @property
    def caps(self):
        return sorted({s["epoch_cap"] for s in self.every_run if s["epoch_cap"] is not None})

    def name(self, alg):
        """An algorithm's name as its runs give it (a figure's label), else the table's, else the
        experiment file's stem."""
        for (_, a), infos in self.runs.items():
            if a == alg and infos:
                return infos[0]["algorithm"]
        return tables.algorithms().by_experiment.get(alg, {}).get("name", alg)

    def run_name(self, env, alg):
        """The runs' directory name under runs/: the experiment's name, which the reference set
        prefixes with "reference-"."""
        return self.selection.get("prefix", "") + f"{env}-{alg}"

    def figures_of(self, kind, env, alg=None):
        """PNG figures of `kind` for an environment (and algorithm), in the order qdplot wrote them;
        entries of an older qdplot.json without names are matched by their runs."""
        name = self.name(alg) if alg else None
        r_algs = [alg] if alg else self.algs
        dirs = {str(s["dir"].resolve()) for s in (self.runs[(env, alg)] if alg else
                                                  [s for a in self.algs for s in self.runs[(env, a)]])}
        out = []
        for f in self.figures:
            if f["kind"] != kind or f["format"] != "png":
                continue
            if f.get("environment") is not None:
                # qdplot names the environment by its variant, which the runs' observation may qualify.
                variants = {env} | {s["run"].env for a in r_algs for s in self.runs[(env, a)]}
                if f["environment"] in variants and (alg is None or f.get("algorithm") == name):
                    out.append(f["file"])
            elif any(str(_resolve(self.out, r)) in dirs for r in f.get("runs", [])):
                out.append(f["file"])
        return out


def _resolve(base, path):
    from pathlib import Path
    p = Path(path)
    return (p if p.is_absolute() else base / "figures" / p).resolve()


def fmt(x, digits=1):
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def percent(elites, of):
    return fmt(100 * elites / of, 2) if of else "n/a"


def ratio(measured, estimate):
    return f"{measured / estimate:.2f}" if estimate > 0 else "n/a"


def mixing_text(summaries):
    """The median over runs of the share of parameter-space offspring in each run's last loop, or '-'."""
    values = [s["mixing"] for s in summaries if not math.isnan(s["mixing"])]
    plotted = any(tables.algorithms().plots_mixing_ratio(s["algorithm"]) for s in summaries)
    return fmt(stats.nearest(values, 50), 2) if plotted and values else "-"


def cap_caption(summaries):
    """A sentence for a table that holds capped runs, or None."""
    caps = sorted({s["epoch_cap"] for s in summaries if s["epoch_cap"] is not None})
    if not caps:
        return None
    return (f"**Autoencoder epochs capped at {' / '.join(map(str, caps))} per loop** in the runs marked so (column "
            f"'autoencoder epochs per loop'); the paper trains up to {tables.algorithms().paper_epochs} with early "
            "stopping, so PoMS, PoMS-no-jacobian and MAPE-DDE are handicapped in this table.")


# The experiment files a report ran (qdreport --configs), as the header names them.
CONFIG_SETS = {
    "reference": "the reference code's configurations, which made the paper's figures (experiments/reference/; "
                 "experiments/README.md, \"The reference configuration set\", lists how they differ from the "
                 "paper's text)",
    "paper-text": "the paper's text (experiments/<environment>/; experiments/README.md lists how the reference "
                  "code's configurations differ)",
}
# Evaluation counts at which the diagnostics section reads the mixing ratio.
RATIO_AT = (20000, 50000, 100000, 200000, 300000, 500000, 1000000, 2000000)


# ---- sections ---------------------------------------------------------------------------------

def title(r):
    lines = [f"# {r.header.get('title') or 'PoMS reproduction report'}", ""]
    if r.header.get("preface"):
        lines += [r.header["preface"].rstrip("\n"), ""]
    return lines


def header(r):
    h, sel = r.header, r.selection
    built = collections.Counter(s["built_for"] for s in r.every_run)
    if sel.get("evaluations") is not None:
        budget = (f"{sel['evaluations']} evaluations per run (qdrun --evaluations: loops chosen per algorithm to "
                  "reach at least this)")
    elif sel.get("loops") is not None:
        budget = f"experiment.loops = {sel['loops']} for every run"
    else:
        budget = "the experiment files' own"
    caps = r.caps
    lines = [f"- date: {h.get('date', '?')}", f"- qdrun: {h.get('qdrun', '?')}", f"- machine: {h.get('machine', '?')}",
             "- runs made on: " + "; ".join(f"{m} ({n} run{'s' if n != 1 else ''})" for m, n in sorted(built.items())),
             f"- seeds: {sel.get('seeds', '?')}", f"- budget: {budget}",
             "- autoencoder epochs: " + (f"**capped at {' / '.join(map(str, caps))} per loop** "
                                         "(representation.max_epochs; the paper allows 20 000 with early stopping, "
                                         "so AE-based algorithms are handicapped in this report; every table and "
                                         "figure they affect says so)" if caps else
                                         "as in the experiment files (20 000 per loop, early stopping; no cap)")]
    if sel.get("configs"):
        lines.append("- configuration set: " + CONFIG_SETS.get(sel["configs"], sel["configs"]))
    if sel.get("set"):
        lines.append("- extra settings: " + ", ".join(f"`{s}`" for s in sel["set"]))
    if h.get("sweep"):
        lines.append(f"- sweep of this invocation: {h['sweep']}")
    lines.append(f"- report command: `{h.get('command', '?')}`")
    if h.get("regenerated"):
        lines.append(f"- regenerated from this directory's files (study.toml, runs/): `{h['regenerated']}`")
    lines.append(f"- commands are shown as run from {h.get('commands_from', 'the repository root')}")
    for note in h.get("notes", []):
        lines.append(f"- note: {note}")
    lines.append("")
    spaces = sorted({(s["index_space"], s["index_space_label"]) for s in r.every_run if s["index_space"]})
    walker = "".join(f" The Walker's is also given in % of {n} = {label}, the reference's own index space, which the "
                     "paper's percentages appear to use (experiments/README.md)." for n, label in spaces)
    lines.append("Coverage is the percentage of all cells of the environment's grid." + walker + " Median and "
                 "quartiles over seeds use numpy's 'nearest' rule, as the figures (and the reference's plots). Wall "
                 "time is the run's own (cumulative over resumed sessions, training included); evaluations/s = "
                 "evaluations / wall time with the run's worker count while other runs shared the machine.")
    return lines


def environment(r, env):
    """One environment: the coverage table per algorithm, the figures, and every run."""
    lines = ["", f"## {env}", ""]
    env_runs = [s for a in r.algs for s in r.runs[(env, a)]]
    cells = next((s["cells"] for s in env_runs if s["cells"]), 0)
    index_space = next((s["index_space"] for s in env_runs if s["index_space"]), None)
    # Coverage in % of the grid's cells, and for the Walker also in % of its index space.
    of = [cells] + ([index_space] if index_space else [])
    pct_heads = "".join(f"coverage % of {c} | " for c in of)
    rows = []
    for a in r.algs:
        infos = r.runs[(env, a)]
        done = [s for s in infos if s["status"] == "complete"]
        name = r.name(a)
        if not infos:
            rows.append(f"| {name} | 0 |" + " |" * (7 + len(of)))  # 9 + len(of) columns
            continue
        if not done:  # only unfinished runs: no final coverage yet, and how far they got
            rows.append(f"| {name} | 0/{len(infos)} | {max(s['evaluations'] for s in infos)} so far | "
                        "none complete |" + " |" * (4 + len(of)) + f" {epochs_text(infos)} |")
            continue
        el = [s["elites"] for s in done]
        walls = [s["wall"] for s in done]
        rates = [s["evaluations"] / s["wall"] for s in done if s["wall"] > 0]
        n = stats.nearest
        pcts = "".join(f"{percent(n(el, 50), c)} ({percent(n(el, 25), c)}-{percent(n(el, 75), c)}) | " for c in of)
        rows.append(f"| {name} | {len(done)}/{len(infos)} | {done[0]['evaluations']} | "
                    f"{n(el, 50)} ({n(el, 25)}-{n(el, 75)}) | {pcts}{fmt(n(walls, 50))} | "
                    f"{fmt(n([s['train'] for s in done], 50))} | {fmt(n(rates, 50), 0)} | "
                    f"{mixing_text(done)} | {epochs_text(infos)} |")
    caption = cap_caption(env_runs)
    if caption:
        lines += [caption, ""]
    lines += ["| algorithm | complete runs | evaluations | final coverage, cells: median (q25-q75) | " + pct_heads +
              "wall s / run (median) | of which training s | evaluations/s (median) | mixing ratio, last loop "
              "(median) | autoencoder epochs per loop |",
              "|---|---|---|---|" + "---|" * len(of) + "---|---|---|---|---|"] + rows
    for f in r.figures_of("coverage", env):
        lines += ["", f"![coverage {env}](figures/{f})", ""]
    qd = qd_table(r, env)
    lines += qd[1:] if lines[-1] == "" else qd
    for kind in ("map", "traces", "latents", "losses"):
        for a in r.algs:
            for f in r.figures_of(kind, env, a):
                lines.append(f"![{kind} {env} {r.name(a)}](figures/{f})")
        lines.append("")
    lines += ["<details><summary>every run</summary>", ""] + ([caption, ""] if caption else [])
    lines += ["| algorithm | seed | loops | evaluations | elites | " + pct_heads + "wall s | training s | "
              "evaluations/s | workers | status | mixing ratio, last loop | autoencoder epochs per loop |",
              "|---|---|---|---|---|" + "---|" * len(of) + "---|---|---|---|---|---|---|"]
    for a in r.algs:
        for s in r.runs[(env, a)]:
            rate = s["evaluations"] / s["wall"] if s["wall"] > 0 else math.nan
            pcts = "".join(f"{percent(s['elites'], c)} | " for c in of)
            lines.append(f"| {r.name(a)} | {s['seed']} | {s['loops']} | {s['evaluations']} | {s['elites']} | "
                         f"{pcts}{fmt(s['wall'])} | {fmt(s['train'])} | {fmt(rate, 0)} | {s['workers']} | "
                         f"{s['status']} | {mixing_text([s])} | {epochs_text([s])} |")
    lines += ["", "</details>"]
    return lines


def qd_table(r, env):
    """The QD metrics of an environment's complete runs (metrics.csv's last row), or the sentence
    saying its task has no fitness."""
    done = {a: [s for s in r.runs[(env, a)] if s["status"] == "complete"] for a in r.algs}
    if not any(s["has_fitness"] for infos in done.values() for s in infos):
        return ["", "QD metrics: no task fitness (the environment declares none: metrics.csv's qd_score, max_fitness "
                    "and mean_fitness are empty).", ""]
    n = stats.nearest
    lines = ["", "QD metrics at the end of the complete runs (metrics.csv's last row): the QD score is the sum over the "
                 "elites of fitness minus the task's lower bound (`qdrun --describe` and the experiment file state "
                 "it); median (q25-q75) over seeds.", "",
             "| algorithm | complete runs | evaluations | QD score | max fitness | mean fitness |", "|---|---|---|---|---|---|"]
    for a, infos in done.items():
        infos = [s for s in infos if s["has_fitness"]]
        if not infos:
            continue
        cols = []
        for key, digits in (("qd_score", 0), ("max_fitness", 2), ("mean_fitness", 2)):
            v = [s[key] for s in infos]
            cols.append(f"{fmt(n(v, 50), digits)} ({fmt(n(v, 25), digits)}-{fmt(n(v, 75), digits)})")
        lines.append(f"| {r.name(a)} | {len(infos)} | {infos[0]['evaluations']} | " + " | ".join(cols) + " |")
    for f in r.figures_of("qd", env):
        lines += ["", f"![QD metrics {env}](figures/{f})"]
    return lines + [""]


def environments(r):
    lines = []
    for env in r.envs:
        lines += environment(r, env)
    return lines


def time_per_million(r):
    threads = r.header.get("hardware_threads", "?")
    lines = ["", "## Time per million evaluations", "",
             f"Sum of the runs' wall seconds divided by their evaluations, x 10^6 (one run's time per million "
             f"evaluations, all algorithms of the environment together, training included, on this machine with "
             f"{threads} hardware threads shared by the concurrent runs)." +
             (" The autoencoder's training time depends on its epochs: a cap makes these times shorter than the "
              "paper's settings would." if r.caps else ""), "",
             "| environment | runs | seconds per 10^6 evaluations (one run) | autoencoder epochs per loop |",
             "|---|---|---|---|"]
    for env in r.envs:
        env_runs = [s for a in r.algs for s in r.runs[(env, a)]]
        complete = [s for s in env_runs if s["status"] == "complete"]
        ev = sum(s["evaluations"] for s in complete)
        if ev:
            secs = sum(s["wall"] for s in complete) / ev * 1e6
            lines.append(f"| {env} | {len(env_runs)} | {secs:.0f} | {epochs_text(env_runs)} |")
    return lines


def cost(r):
    """The dry-run estimate made before the sweep's first run against the time the runs took."""
    if not (r.out / "estimate.txt").exists():
        return []
    per_run, total = read_estimate(r.out / "estimate.txt")
    invocations = read_invocations(r.out / "invocations.csv")
    lines = ["", "## Cost: the estimate against the measured time", "",
             "Before the sweep's first run, qdreport saved its plan and estimated cost (`qdrun --dry-run` of the "
             "qdrun that ran the sweep, by the model of docs/performance.md at that revision) in "
             "REPORT_DIR/estimate.txt; every invocation of the sweep is logged in "
             "REPORT_DIR/invocations.csv. The estimate is in core-hours; a run's measured time is its own wall "
             "time, so a run with w workers is compared with its estimated wall time, the episodes' core-hours / w "
             "plus the training (for one worker, the core-hours).", "",
             "| environment | algorithm | runs compared | estimate, core-h per run (median) | estimate, wall h per run "
             "(median) | measured, wall h per run (median) | measured / estimate |", "|---|---|---|---|---|---|---|"]
    est_sum = core_sum = wall_sum = 0.0
    compared = 0
    for env in r.envs:
        for a in r.algs:
            key = r.run_name(env, a) + "/seed-"
            rows = [(per_run[f"{key}{s['seed']}"], _workers(s), s["wall"] / 3600) for s in r.runs[(env, a)]
                    if s["status"] == "complete" and f"{key}{s['seed']}" in per_run and s["wall"] > 0]
            if not rows:
                continue
            compared += len(rows)
            core = [e["core_h"] for e, _, _ in rows]
            expected = [e["core_h"] - e["episodes_h"] + e["episodes_h"] / w for e, w, _ in rows]
            walls = [m for _, _, m in rows]
            core_sum += sum(core)
            est_sum += sum(expected)
            wall_sum += sum(walls)
            c, e, w = (stats.nearest(v, 50) for v in (core, expected, walls))
            lines.append(f"| {env} | {r.name(a)} | {len(rows)} | {c:.3f} | {e:.3f} | {w:.3f} | {ratio(w, e)} |")
    lines.append("")
    if compared:
        lines.append(f"All {compared} compared runs: estimate {core_sum:.2f} core-h, {est_sum:.2f} h of run wall time "
                     f"with their workers; measured {wall_sum:.2f} h of run wall time (ratio {ratio(wall_sum, est_sum)}).")
    if total:
        sweeps = total["sweeps"]
        text = ("The whole sweep" + (f" ({sweeps} sweeps one after another, each of its own runs: their dry-runs "
                                     "add up)" if sweeps > 1 else "") +
                f": estimate {total['core_h']:.2f} core-hours, about {total['wall_h']:.2f} h of wall time" +
                (f" with {total['jobs']} at a time on {total['cores']} cores" if total["jobs"] else ""))
        if compared and compared == len(per_run) and total["jobs"]:
            jobs = total["jobs"]
            text += (f"; measured: the runs' wall times add to {wall_sum:.2f} h, {wall_sum / jobs:.2f} h with {jobs} at "
                     f"a time (ratio {ratio(wall_sum / jobs, total['wall_h'])})")
        elif compared and compared < len(per_run):
            text += f" ({len(per_run) - compared} of its {len(per_run)} runs not complete yet)"
        lines.append(text + ".")
    if invocations:
        secs = sum(float(i.get("wall_seconds") or 0) for i in invocations)
        unknown = sum(1 for i in invocations if not i.get("wall_seconds"))
        text = (f"The sweep ran in {len(invocations)} invocation{'s' if len(invocations) != 1 else ''} of qdreport, "
                f"{secs / 3600:.2f} h of wall time in all" +
                (f" ({unknown} of them killed without logging its time)" if unknown else ""))
        if total and compared == len(per_run):
            text += f" (ratio to the estimate {ratio(secs / 3600, total['wall_h'])})"
        lines.append(text + ": this includes runs interrupted and resumed, and anything else the machine did.")
    return lines


def _workers(s):
    """A run's worker count from its provenance (1 when it does not say)."""
    try:
        return max(1, int(s["workers"]))
    except (TypeError, ValueError):
        return 1


def lengthening(r):
    """Per environment: the breeding runs' time per evaluation in each loop against their loop 0's,
    and the cells they found by each loop's middle, the quantities an experiment file's [cost] table
    states for qdrun --dry-run; over the loops every complete run has (complete at its own budget is
    enough: a run being extended is still a measurement)."""
    algs = tables.algorithms()
    lines = []
    for env in r.envs:
        middles, n, by_alg, cells_by_alg = {}, 0, {}, {}
        for a in r.algs:
            if algs.is_sampler(a):  # random search: its episodes do not lengthen as the archive spreads
                continue
            for s in r.runs[(env, a)]:
                rates, ends = s["loop_rates"], s["loop_ends"]
                # A run complete at its own budget counts for its loops, short of the report's or not.
                if not rates.get(0) or not s["status"].startswith("complete"):
                    continue
                n += 1
                mine, my_cells = by_alg.setdefault(r.name(a), {}), cells_by_alg.setdefault(r.name(a), {})
                for L, rate in rates.items():
                    if L >= 1:
                        mine.setdefault(L, []).append(rate / rates[0])
                        middles[L] = (int(ends[L - 1]["evaluations"]) + int(ends[L]["evaluations"])) // 2
                        my_cells.setdefault(L, []).append((ends[L - 1]["elites"] + ends[L]["elites"]) / 2)
        per_loop = {L: [v for mine in by_alg.values() for v in mine.get(L, [])] for L in middles}
        loops = [L for L in sorted(per_loop) if len(per_loop[L]) == n]
        if not loops:
            continue
        if not lines:
            lines = ["", "## Episode lengthening: time per evaluation against loop 0's", "",
                     "The mean over the complete runs of the algorithms that breed from elites (random search left "
                     "out) of each loop's wall time per evaluation (training out) divided by the run's loop 0's. "
                     "An experiment file's `[cost]` table states this for `qdrun --dry-run` (docs/user-guide.md, "
                     "\"How long will it take\"); the lines under each table are that table for these runs, with "
                     "`cells`, the mean of the cells found by each loop's middle (they size a representation's "
                     "training data). Below the mean, each algorithm's own (episodes lengthen as far as its archive "
                     "spreads)."]
        means = [sum(per_loop[L]) / n for L in loops]

        def cost_table(times, cells):
            return ["```toml", "[cost]", "evaluations = [0, " + ", ".join(str(middles[L]) for L in loops) + "]",
                    "offspring_time = [1.0, " + ", ".join(f"{t:.2f}" for t in times) + "]",
                    "cells = [0, " + ", ".join(str(int(c + 0.5)) for c in cells) + "]", "```"]

        def mean_cells(tables, L):
            values = [v for t in tables for v in t.get(L, [])]
            return sum(values) / len(values)

        lines += ["", f"{env}, {n} runs:", "", "| loop | " + " | ".join(map(str, loops)) + " |",
                  "|---|" + "---|" * len(loops),
                  "| evaluations at its middle | " + " | ".join(str(middles[L]) for L in loops) + " |",
                  "| time per evaluation / loop 0's | " + " | ".join(f"{m:.2f}" for m in means) + " |"]
        if len(by_alg) > 1:  # episodes lengthen by how far each algorithm's archive spreads
            lines += [f"| {name} ({len(mine[loops[0]])} run{'s' if len(mine[loops[0]]) != 1 else ''}) | " +
                      " | ".join(f"{sum(mine[L]) / len(mine[L]):.2f}" for L in loops) + " |"
                      for name, mine in by_alg.items()]
        lines += [""] + cost_table(means, [mean_cells(cells_by_alg.values(), L) for L in loops])
        if len(by_alg) > 1:  # what a file of one algorithm states: its own lengthening and spread
            lines += ["", "<details><summary>Each algorithm's own [cost] table</summary>", ""]
            for name, mine in by_alg.items():
                lines += [f"{name}:", ""] + cost_table([sum(mine[L]) / len(mine[L]) for L in loops],
                                                       [mean_cells([cells_by_alg[name]], L) for L in loops]) + [""]
            lines.append("</details>")
    return lines


PAPER_AT = (20000, 50000, 100000, 200000, 300000, 500000, 1000000, 2000000)


def coverage_at(summary, evaluations, of):
    """A run's coverage in % of `of` cells after `evaluations` (its last row at or before), None when
    the run stopped before."""
    rows = summary["run"].metrics
    if not rows or rows[-1]["evaluations"] < evaluations:
        return None
    elites = [m["elites"] for m in rows if m["evaluations"] <= evaluations]
    return 100.0 * (elites[-1] if elites else 0) / of


def paper(r):
    """Per variant with a paper figure (environments.toml [[paper_figure]]): the median over seeds
    of our coverage against the paper's curve at the same evaluations (share/paper-curves.csv)."""
    envs = tables.environments()
    lines = []
    for env in r.envs:
        env_runs = [s for a in r.algs for s in r.runs[(env, a)]]
        variants = {s["run"].env for s in env_runs}
        figure = next((envs.paper_figures[v] for v in sorted(variants) if v in envs.paper_figures), None)
        if not figure or len(variants) != 1:
            continue
        rows, used, both = [], set(), {}
        by_seed, papers = {}, {}  # {evaluations: {seed: {name: coverage}}}, {evaluations: {name: paper's}}
        for a in r.algs:
            cells = []
            for e in PAPER_AT:
                ours = []
                for s in r.runs[(env, a)]:
                    of = s["index_space"] if figure["percent_of"] == "index_space" else s["cells"]
                    c = coverage_at(s, e, of) if of else None
                    if c is not None:
                        ours.append(c)
                        by_seed.setdefault(e, {}).setdefault(s["seed"], {})[r.name(a)] = c
                theirs = tables.paper_value(figure["figure"], r.name(a), e)
                if theirs:
                    papers.setdefault(e, {})[r.name(a)] = theirs
                if ours and theirs:
                    used.add(e)
                    med = stats.nearest(ours, 50)
                    cells.append(f"{med:.2f} / {theirs:.2f} = {med / theirs:.2f} ({len(ours)})")
                    both.setdefault(e, []).append((r.name(a), med, len(ours), theirs))
                else:
                    cells.append("")
            rows.append((r.name(a), cells))
        used = [e for e in PAPER_AT if e in used]
        if not used:
            continue
        if not lines:
            lines = ["", "## Against the paper's figures", "",
                     "Coverage read off the paper's figures (the median curves of the coverage figures the authors "
                     "publish with their code, digitised every 10 000 evaluations: share/paper-curves.csv; "
                     "results/paper-curves/ has the digitiser and its check) against ours at the same number of "
                     "evaluations: the median over the seeds whose runs reached it (their count in brackets), "
                     "ours / paper = ratio."]
        what = ("% of " + str(next(s["index_space"] for s in env_runs)) if figure["percent_of"] == "index_space"
                else "% of the grid's cells")
        made = {"reference": "the reference code's configurations", "paper-text": "the paper's text"}.get(
            figure["configs"], figure["configs"])
        ran = r.selection.get("configs")
        note = f"; this report ran {'the same' if ran == figure['configs'] else 'another'} set" if ran else ""
        lines += ["", f"{env} ({what}; the figure was made with {made}{note}):", "",
                  "| algorithm | " + " | ".join(f"at {e:,}".replace(",", " ") for e in used) + " |",
                  "|---|" + "---|" * len(used)]
        lines += [f"| {name} | " + " | ".join(c for c, e in zip(cells, PAPER_AT) if e in used) + " |"
                  for name, cells in rows]
        lines += leaders(both)
        lines += leaders_by_seed([r.name(a) for a in r.algs], used, by_seed, papers)
    return lines


def leaders(both):
    """Which algorithm leads at each budget, ours (the medians) beside the paper's, among the
    algorithms with both at that budget: the claim a coverage figure makes. `both`: {evaluations:
    [(name, our median, seeds, paper's value)]}."""
    budgets = [e for e in PAPER_AT if len(both.get(e, [])) >= 2]
    if not budgets:
        return []

    def ranked(e, k):
        first, second = sorted(both[e], key=lambda row: -row[k])[:2]
        return first, second, f"{100 * (first[k] / second[k] - 1):.1f} %" if second[k] > 0 else "-"

    lines = ["", "Which algorithm leads, ours and the paper's, among the algorithms above with both at that "
             "budget; the lead is the leader's coverage over the runner-up's (ours: medians, seeds in brackets).",
             "", "| at | ours: leader | runner-up | lead | the paper's: leader | runner-up | lead | same leader |",
             "|---|---|---|---|---|---|---|---|"]
    for e in budgets:
        (a, am, an, _), (b, bm, bn, _), lead = ranked(e, 1)
        (pa, _, _, pam), (pb, _, _, pbm), plead = ranked(e, 3)
        at = f"{e:,}".replace(",", " ")
        lines.append(f"| {at} | {a} {am:.2f} ({an}) | {b} {bm:.2f} ({bn}) | {lead} | {pa} {pam:.2f} | "
                     f"{pb} {pbm:.2f} | {plead} | {'yes' if a == pa else 'no'} |")
    return lines


def leaders_by_seed(names, budgets, by_seed, papers):
    """The leader seed by seed at each budget, beside the paper's curves: medians over unequal numbers
    of seeds can hide that one algorithm leads in every seed, or in none. `by_seed`: {evaluations:
    {seed: {name: coverage}}}; `papers`: {evaluations: {name: the paper's coverage}}."""

    def row(at, label, values, paper_leader):
        if len(values) < 2:
            return None
        ranked = sorted(values, key=lambda name: -values[name])
        first, second = ranked[0], ranked[1]
        lead = f"{100 * (values[first] / values[second] - 1):.1f} %" if values[second] > 0 else "-"
        place = f"{ranked.index(paper_leader) + 1} of {len(ranked)}" if paper_leader in values else "-"
        return (f"| {at} | {label} | " + " | ".join(f"{values[n]:.2f}" if n in values else "-" for n in names) +
                f" | {first} | {lead} over {second} | {place} |")

    rows = []
    for e in budgets:
        theirs = papers.get(e, {})
        paper_leader = max(theirs, key=theirs.get) if theirs else None
        at = f"{e:,}".replace(",", " ")
        here = [row(at, f"seed {seed}", ours, paper_leader) for seed, ours in sorted(by_seed.get(e, {}).items())]
        if any(here):
            rows += here + [row(at, "the paper's curves", theirs, paper_leader)]
    rows = [x for x in rows if x]
    if not rows:
        return []
    return ["", "Seed by seed, the same coverage (-: that run stopped before the budget), the leader's lead over the "
            "runner-up, and where the paper's leader at that budget places among our runs of that seed:", "",
            "| at | seed | " + " | ".join(names) + " | leader | lead | the paper's leader's place |",
            "|---|---|" + "---|" * len(names) + "---|---|---|"] + rows


def diagnostics(r):
    """Per environment: the mixing ratio as the paper's figures aggregate it, the representation's
    epochs per loop and the final elites' parameter norms: what tells whether the latent branch of
    PoMS works in the regime the paper describes."""
    algs = tables.algorithms()
    lines = []
    for env in r.envs:
        rows_ratio, rows_runs = [], []
        for a in r.algs:
            infos = r.runs[(env, a)]
            if not infos:
                continue
            if any(algs.plots_mixing_ratio(s["algorithm"]) for s in infos):
                ratio = stats.paper_mixing_ratio([s["run"] for s in infos])
                if ratio is not None:
                    ev, mean, _ = ratio
                    rows_ratio.append((r.name(a), len(infos), [fmt(float(mean[e - 1]), 3) if e <= ev.size else ""
                                                               for e in RATIO_AT],
                                       f"{fmt(float(mean[-1]), 3)} ({ev.size})"))
            for s in infos:
                epochs = (s.get("epochs_per_loop") or []) if s["autoencoder"] else []  # PCA's are 0
                later = epochs[1:]
                rows_runs.append(f"| {r.name(a)} | {s['seed']} | {s['evaluations']} | "
                                 f"{epochs[0] if epochs else '-'} | {later[0] if later else '-'} | "
                                 f"{int(stats.nearest(later, 50)) if later else '-'} | "
                                 f"{f'{min(later)}-{max(later)}' if later else '-'} | "
                                 f"{fmt(s.get('parameter_norm_median', math.nan), 2)} | "
                                 f"{fmt(s.get('parameter_norm_max', math.nan), 2)} |")
        if not rows_ratio and not any(s.get("epochs_per_loop") for a in r.algs for s in r.runs[(env, a)]):
            continue
        if not lines:
            lines = ["", "## Diagnostics: mixing ratio, training, parameter norms", "",
                     "The mixing ratio is the share of a batch's offspring made in parameter space, aggregated as "
                     "the paper's figures aggregate it: each batch's value repeated over its evaluations (loop 0 "
                     "given the first value), the mean over the seeds that reached each evaluation, then a centred "
                     "moving average over 10 000 evaluations. Epochs are the representation's training epochs per "
                     "loop (training.csv; loop 0 trains on the initial samples). Parameter norms are the Euclidean "
                     "norms of the final elites' parameter vectors (archive.csv), median and largest."]
        used = [e for e in RATIO_AT if any(cells[RATIO_AT.index(e)] for _, _, cells, _ in rows_ratio)]
        lines += ["", f"### {env}", ""]
        if rows_ratio:
            lines += ["| algorithm | runs | " + "".join(f"mixing ratio at {e:,} | ".replace(",", " ") for e in used) +
                      "at the last evaluation (evaluations) |", "|---|---|" + "---|" * (len(used) + 1)]
            lines += [f"| {name} | {n} | " + "".join(cells[RATIO_AT.index(e)] + " | " for e in used) + end + " |"
                      for name, n, cells, end in rows_ratio]
            lines.append("")
        lines += ["| algorithm | seed | evaluations | epochs, loop 0 | epochs, loop 1 | epochs, loops >= 1 (median) | "
                  "epochs, loops >= 1 (min-max) | elite parameter norm (median) | elite parameter norm (max) |",
                  "|---|---|---|---|---|---|---|---|---|"] + rows_runs
    return lines


def revisions(r):
    return ["", f"Git revisions of the runs: {', '.join(sorted({s['git'] for s in r.every_run}))}."]


SECTIONS = [title, header, environments, paper, diagnostics, time_per_million, cost, lengthening, revisions]


def render(r):
    """REPORT.md's text: every section, and at the end of the part under each "## " heading, the
    addenda that name that heading."""
    lines = []
    for section in SECTIONS:
        lines += section(r)
    parts, current = [], []
    for line in lines:
        if line.startswith("## ") and current:
            parts.append(current)
            current = []
        current.append(line)
    parts.append(current)
    out = []
    for part in parts:
        while part and part[-1] == "" and any(a.get("after") == part[0] for a in r.addenda):
            part = part[:-1]
        out += part
        for add in r.addenda:
            if add.get("after") == part[0]:
                out += ([] if out and out[-1] == "" else [""]) + [add["text"].strip("\n"), ""]
    return "\n".join(out).rstrip("\n") + "\n"
