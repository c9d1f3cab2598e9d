#!/usr/bin/python3
"""Checks the documentation against the repository, so that what it says stays true.

  check_docs.py SOURCE_DIR                 the checks below that need no build
  check_docs.py SOURCE_DIR --qdrun QDRUN   only the command-line output (qdrun --list, --describe)

  * README.md is a front page of at most 200 lines, and names the paper, the licence and docs/.
  * Every relative link of every Markdown file resolves to a file or directory of the tree.
  * A code block preceded by `<!-- file: PATH -->` is exactly the file PATH (so the README's plugin
    is the one tests/install builds, and the plugin guide's example the one tests/docs builds).
  * No "spec N.N" reference to a document users do not have, in any Markdown file, experiment file,
    source file or script, qdplot or qdreport, or in qdrun's --list and --describe output.
  * The algorithm table, share/algorithms.toml, is the only one: the README's table lists its
    entries with the same representation and mutator, every experiments/<variant>/<name>.toml of the
    paper's variants holds the (representation, mutator, initial) of its entry, and the tools
    (share/qdplot, qdreport, qdresults and the qdtools package) hold no algorithm names of their own.
  * The tutorial (docs/tutorial.md) is at most 150 lines; tests/docs/tutorial.sh runs its commands.
"""
import fnmatch
import os
import re
import subprocess
import sys
from pathlib import Path

sys.dont_write_bytecode = True  # nothing written into the source tree
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "experiments"))
from paper_table import load as load_experiment  # noqa: E402  (an experiment file with its includes, as qdrun merges them)
sys.path.insert(0, str(Path(__file__).resolve().parent.parent.parent / "share"))
from qdtools import tables  # noqa: E402  (the tools' reader of share/'s tables)

SPEC = re.compile(r"\bspec(?:\s+sections?)?\s*(?:§\s*)?\d+(?:\.\d+)*|\(spec\)|poms-reference\.md", re.IGNORECASE)
SKIP_DIRS = {".git", "__pycache__"}
failures = []


def fail(text):
    failures.append(text)


def files(root, pattern):
    # Walks only the source tree: build trees, run outputs and .git are never entered, because tests
    # running beside this check create and delete files there (rglob would walk them first and fail
    # on a directory that vanished mid-walk).
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        top = Path(dirpath) == root
        dirnames[:] = [d for d in dirnames
                       if d not in SKIP_DIRS and not (top and (d.startswith("build") or d in ("runs", "out")))]
        found += [Path(dirpath) / f for f in filenames if fnmatch.fnmatch(f, pattern)]
    yield from sorted(found)


def check_readme(root):
    text = (root / "README.md").read_text()
    lines = text.count("\n")
    if lines > 200:
        fail(f"README.md has {lines} lines (at most 200: details belong in docs/)")
    for needle, what in (("arxiv.org/abs/2104.13424", "a link to the paper"), ("@inproceedings", "the paper's BibTeX"),
                         ("LICENSE", "the licence"), ("CITATION.cff", "the citation file"),
                         ("docs/README.md", "the documentation index"), ("scripts/quickstart.sh", "the quick start"),
                         ("scripts/test.sh", "the test command")):
        if needle not in text:
            fail(f"README.md does not mention {what} ({needle})")
    for name in ("LICENSE", "CITATION.cff", "CHANGELOG.md", "docs/README.md", "docs/tutorial.md", "docs/user-guide.md",
                 "docs/plugin-guide.md", "docs/performance.md", "docs/performance-history.md", "docs/design.md",
                 "docs/reference-behaviour.md", "results/README.md", "examples/README.md"):
        if not (root / name).is_file():
            fail(f"{name} is missing")
    tutorial = root / "docs" / "tutorial.md"
    if tutorial.is_file() and tutorial.read_text().count("\n") > 150:
        fail(f"docs/tutorial.md has {tutorial.read_text().count(chr(10))} lines (at most 150: a newcomer finishes it)")


LINK = re.compile(r"\]\(([^)\s]+)\)")


def check_links_and_blocks(root):
    for md in files(root, "*.md"):
        text = md.read_text()
        for target in LINK.findall(text):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = target.split("#", 1)[0]
            if path and not (md.parent / path).exists():
                fail(f"{md.relative_to(root)}: link to {target}, which does not exist")
        for m in re.finditer(r"<!-- file: (\S+) -->\n```[a-z]*\n(.*?)```\n", text, re.DOTALL):
            source = root / m.group(1)
            if not source.is_file():
                fail(f"{md.relative_to(root)}: the code block of {m.group(1)}: no such file")
            elif source.read_text() != m.group(2):
                fail(f"{md.relative_to(root)}: the code block of {m.group(1)} differs from the file")
        if text.count("<!-- file: ") != len(re.findall(r"<!-- file: \S+ -->\n```", text)):
            fail(f"{md.relative_to(root)}: a '<!-- file: -->' marker is not directly followed by a code block")


def check_spec_references(root):
    targets = list(files(root, "*.md")) + list(files(root / "experiments", "*.toml"))
    targets += [root / "share" / name for name in ("qdplot", "qdreport", "qdresults")]
    # Code comments too: a reader of the sources cannot follow a reference to a document they lack.
    for pattern in ("*.cpp", "*.hpp", "*.py", "*.sh", "CMakeLists.txt"):
        targets += [p for p in files(root, pattern) if p.resolve() != Path(__file__).resolve()]
    for path in targets:
        rel = str(path.relative_to(root))
        for n, line in enumerate(path.read_text().splitlines(), 1):
            m = SPEC.search(line)
            if m:
                fail(f"{rel}:{n}: '{m.group(0)}' cites a document that is not in the repository (cite the paper, "
                     "docs/reference-behaviour.md or a README)")


# experiments/ directories that are not the PoMS paper's variants: the smoke runs, the reference set
# (its environment directories are checked one level down), and the CMA-ME
# benchmark's files (experiments/README.md), whose algorithms share/algorithms.toml does not list yet.
NOT_PAPER_DIRS = {"smoke", "reference", "lp-sphere", "lp-rastrigin"}


def check_algorithm_table(root):
    table = tables.load("algorithms.toml", root / "share")["algorithm"]
    by_name = {a["name"]: a for a in table}
    # The README's table: | name | `experiment` | `representation` | `mutator` | summary |
    rows = {}
    for line in (root / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 5 and cells[0] in by_name:
            rows[cells[0]] = [c.strip("`") for c in cells[1:5]]
    if list(rows) != list(by_name):
        fail(f"README.md's algorithm table lists {list(rows)}, share/algorithms.toml {list(by_name)} (same order)")
    for name, row in rows.items():
        a = by_name[name]
        want = [a["experiment"], a["representation"], a["mutator"], a["summary"]]
        if row != want:
            fail(f"README.md: {name} is {row}, share/algorithms.toml says {want}")
    stems = {a["experiment"]: a for a in table}
    variants = [d for d in sorted((root / "experiments").iterdir()) if d.is_dir() and d.name not in NOT_PAPER_DIRS]
    variants += [d for d in sorted((root / "experiments" / "reference").iterdir()) if d.is_dir()]
    if not variants:
        fail("experiments/ holds no variant directories")
    for d in variants:
        names = {p.stem for p in d.glob("*.toml")} - {"base"}
        if names != set(stems):
            fail(f"{d.relative_to(root)}: files {sorted(names)}, share/algorithms.toml {sorted(stems)}")
        for stem in sorted(names & set(stems)):
            cfg = load_experiment(d / f"{stem}.toml")
            got = (cfg.get("representation", {}).get("type", "none"), cfg.get("mutator", {}).get("type"),
                   cfg.get("initial", {}).get("type", "uniform"))
            a = stems[stem]
            want = (a["representation"], a["mutator"], a["initial"])
            if got != want:
                fail(f"{d.relative_to(root)}/{stem}.toml: (representation, mutator, initial) {got}, "
                     f"share/algorithms.toml {want}")
    tools = [root / "share" / name for name in ("qdplot", "qdreport", "qdresults")]
    for script in tools + sorted((root / "share" / "qdtools").rglob("*.py")):
        text = script.read_text()
        for name in by_name:
            if re.search(r"[\"']" + re.escape(name) + r"[\"']", text):
                fail(f"{script.relative_to(root)} spells the algorithm name '{name}' itself (read it from "
                     "algorithms.toml)")


def check_cli(qdrun):
    """qdrun --list and --describe of every component and core table cite no missing document."""
    listing = subprocess.run([qdrun, "--list"], capture_output=True, text=True, check=True).stdout
    outputs = {"--list": listing}
    names = set(re.findall(r"^  (\S+) +\S", listing, re.MULTILINE))  # "  name   summary" under "kinds:" lines
    if len(names) < 10:
        fail(f"qdrun --list names only {sorted(names)}: its format changed? ({listing[:300]!r})")
    for name in sorted(names) + ["experiment", "policy", "output", "evaluation", "plugins", "environment",
                                 "descriptor", "representation", "mutator", "initial"]:
        p = subprocess.run([qdrun, "--describe", name], capture_output=True, text=True)
        if p.returncode != 0:
            fail(f"qdrun --describe {name}: exit code {p.returncode}: {p.stderr.strip()}")
        outputs[f"--describe {name}"] = p.stdout
    for what, text in outputs.items():
        for line in text.splitlines():
            m = SPEC.search(line)
            if m:
                fail(f"qdrun {what}: '{m.group(0)}' in: {line.strip()}")
    return len(outputs)


def main():
    root = Path(sys.argv[1]).resolve()
    if "--qdrun" in sys.argv:
        n = check_cli(sys.argv[sys.argv.index("--qdrun") + 1])
        what = f"qdrun --list and {n - 1} --describe outputs"
    else:
        check_readme(root)
        check_links_and_blocks(root)
        check_spec_references(root)
        check_algorithm_table(root)
        what = "README, links, code blocks, references, algorithm table"
    if failures:
        print("docs check FAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print(f"docs check ok: {what}")


if __name__ == "__main__":
    main()
