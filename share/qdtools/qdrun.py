"""qdrun itself, for what only it can make: replayed trajectories, latent codes, sweeps."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from .tables import SHARE

# The source tree holding these tools (share/..), or None when they are installed.
SOURCE_TREE = SHARE.parent if (SHARE.parent / "CMakeLists.txt").exists() and (SHARE.parent / "core").is_dir() \
    else None


def find_qdrun(explicit=None):
    """--qdrun, $QDRUN, <prefix>/bin/qdrun of an installed copy, PATH, then build/bin of the source
    tree; None when there is none."""
    candidates = [explicit, os.environ.get("QDRUN"), SHARE.parent.parent / "bin" / "qdrun", shutil.which("qdrun"),
                  SHARE.parent / "build" / "bin" / "qdrun"]
    for c in candidates:
        if c and Path(c).is_file() and os.access(c, os.X_OK):
            return str(c)
    return None


def fresh(target, sources):
    """Whether `target` exists and is newer than every existing source."""
    target = Path(target)
    return target.exists() and all(target.stat().st_mtime >= Path(s).stat().st_mtime for s in sources
                                   if Path(s).exists())


def make(qdrun, args, target, sources, tool="qdplot"):
    """Runs `qdrun args` to make `target` unless it is newer than its sources. Returns an error
    text (qdrun's own last line) or None."""
    if fresh(target, sources):
        return None
    Path(target).parent.mkdir(parents=True, exist_ok=True)
    p = subprocess.run([qdrun] + list(map(str, args)), capture_output=True, text=True)
    if p.returncode != 0:
        message = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else f"exit code {p.returncode}"
        print(f"{tool}: qdrun {' '.join(map(str, args))} failed: {message}", file=sys.stderr)
        return message
    return None


def version(qdrun):
    """qdrun --version's first line, or '?'."""
    if not qdrun:
        return "?"
    out = subprocess.run([qdrun, "--version"], capture_output=True, text=True).stdout.strip().splitlines()
    return out[0] if out else "?"
