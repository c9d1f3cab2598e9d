"""study.toml: what a report states that its runs do not (the selection of environments,
algorithms and seeds, the budget, the machine and date the report was made on, the commands, the
notes, text added by hand), written beside REPORT.md every time qdreport writes one. With it,
`qdreport --regenerate DIR` makes the figures and REPORT.md again from the directory's files alone,
without qdrun: so does a study in results/."""
import datetime
import os
import platform
import tomllib
from pathlib import Path

from .. import ToolError

NAME = "study.toml"


def cpu_model():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def this_machine():
    """The facts of the machine and moment a report is written on."""
    return {"date": f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
            "machine": f"{cpu_model()}, {os.cpu_count()} hardware threads, host {platform.node()}",
            "hardware_threads": os.cpu_count()}


def read(directory):
    path = Path(directory) / NAME
    if not path.exists():
        return None
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ToolError(f"{path}: {e}") from e


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        if "\n" in v:
            return '"""\n' + v.replace("\\", "\\\\").replace('"""', '\\"\\"\\"') + '"""'
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        if not v:
            return "[]"
        return "[\n" + "".join(f"  {toml_value(x)},\n" for x in v) + "]"
    raise TypeError(type(v))


def write(directory, study):
    """Writes study.toml: [selection], [header], then any [[addendum]] tables (kept from the file
    there before: they are written by hand)."""
    lines = ["# qdreport's record of this report (share/README.md, \"qdreport\"): regenerate REPORT.md and its",
             "# figures from this directory's files with  share/qdreport --regenerate REPORT_DIR", ""]
    for table in ("selection", "header"):
        lines.append(f"[{table}]")
        for k, v in study.get(table, {}).items():
            if v is not None:
                lines.append(f"{k} = {toml_value(v)}")
        lines.append("")
    for add in study.get("addendum", []):
        lines.append("[[addendum]]")
        for k, v in add.items():
            lines.append(f"{k} = {toml_value(v)}")
        lines.append("")
    path = Path(directory) / NAME
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(lines))
    tmp.replace(path)
