"""The self-test both table checks share: each mutation (file, text, replacement) is applied to a
fresh copy of the experiment directory, and the check must then report it."""
import shutil
import tempfile
from pathlib import Path


def self_test(root, mutations, check, detected=lambda rel, errors: bool(errors)):
    """`check(dir)` -> list of errors; `detected(rel, errors)` says whether the errors name the
    mutation of file `rel`. Returns the failures of the self-test."""
    failures = []
    if check(root):
        failures.append("the files as they are do not pass")
    for rel, old, new in mutations:
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / "experiments"
            shutil.copytree(root, copy)
            path = copy / rel
            text = path.read_text()
            if old not in text:
                failures.append(f"{rel}: '{old}' not found (update MUTATIONS)")
                continue
            path.write_text(text.replace(old, new, 1))
            errors = check(copy)
            if not detected(rel, errors):
                failures.append(f"{rel}: '{old}' -> '{new}' was not detected")
            else:
                print(f"detected {rel}: {old} -> {new}: {errors[0]}")
    return failures
