"""Commands as a report shows them: without the paths of the machine that made it."""
import os
import shlex
from pathlib import Path
from shutil import which

from ..qdrun import SOURCE_TREE
from ..tables import SHARE

# Where commands are shown from: the source tree holding the tools, else the install prefix
# (<prefix>/share/qd/qdtools).
BASE = SOURCE_TREE or SHARE.parent.parent


class Shown:
    def __init__(self, report_dir, qdrun=None):
        self.report_dir = Path(report_dir).resolve()
        prefix = Path(qdrun).resolve().parent.parent if qdrun else None
        self.prefix = None if prefix is None or prefix.is_relative_to(BASE) else prefix

    def __call__(self, argv):
        """`argv` as a shell command: paths inside the report directory as REPORT_DIR/..., inside the
        repository (or the prefix the tools are installed in) relative to it, a program found on PATH
        by its name, paths in the prefix of the qdrun used as PREFIX/..., anything else by its name."""
        words = []
        for word in argv:
            text = str(word)
            if not os.path.isabs(text) and ("/" in text or Path(text).resolve() == self.report_dir) and \
                    os.path.exists(text):  # a path relative to the working directory
                text = os.path.abspath(text)
            if os.path.isabs(text):
                path = Path(os.path.normpath(text))
                if path.is_relative_to(self.report_dir):
                    rel = path.relative_to(self.report_dir)
                    text = "REPORT_DIR" + ("" if rel == Path(".") else f"/{rel}")
                elif path.is_relative_to(BASE):
                    text = str(path.relative_to(BASE))
                elif which(path.name) and Path(which(path.name)).resolve() == path.resolve():
                    text = path.name
                elif self.prefix is not None and path.is_relative_to(self.prefix):
                    text = f"PREFIX/{path.relative_to(self.prefix)}"
                else:
                    text = f".../{path.name}"
            words.append(text)
        return shlex.join(words)

    def origin(self):
        return ("the repository root" if SOURCE_TREE else "the install prefix") + \
            ", with REPORT_DIR for this report's directory" + \
            (" and PREFIX for the install prefix of the qdrun used" if self.prefix else "")
