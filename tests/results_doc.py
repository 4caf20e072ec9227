"""docs/results.md against result.json: the fields the page defines, and the fields a result holds.

A field is defined by a table row of docs/results.md whose first cell names it in back-quotes (one
cell may name several). NAME, TYPE and KIND in a path stand for any robot, message type and command
kind. A documented object with no documented sub-field is a leaf: its inside is described in words.
"""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "results.md"
PLACEHOLDERS = ("NAME", "TYPE", "KIND")


def documented_fields(doc: Path = DOC) -> set[str]:
    fields = set()
    for line in doc.read_text().splitlines():
        if not line.startswith("| `"):
            continue
        first_cell = line.split("|")[1]
        fields.update(re.findall(r"`([A-Za-z_][A-Za-z0-9_.]*)`", first_cell))
    return fields


def result_fields(result: dict, documented: set[str]) -> set[str]:
    """Every field path of `result`, named as the page would name it (placeholders for keys under a
    documented placeholder); recursion stops at a documented path no documented field extends."""
    prefixes = {f.rsplit(".", k)[0] for f in documented for k in range(1, f.count(".") + 1)}
    found: set[str] = set()

    def name_of(parent: str, key: str) -> str:
        path = f"{parent}.{key}" if parent else key
        if path in documented or path in prefixes:
            return path
        for placeholder in PLACEHOLDERS:
            general = f"{parent}.{placeholder}" if parent else placeholder
            if general in documented or general in prefixes:
                return general
        return path

    def walk(parent: str, value) -> None:
        for key, item in value.items():
            path = name_of(parent, str(key))
            found.add(path)
            if isinstance(item, dict) and (path in prefixes or path not in documented):
                walk(path, item)

    walk("", result)
    return found


def undocumented(result: dict, *, named_metrics: bool = False) -> list[str]:
    """Fields of `result` the page does not define (a container whose fields it defines, such as
    robots.NAME, counts as defined). `named_metrics`: a mission file's run, whose `metrics` are the
    ones its file names (docs/missions.md), not the page's."""
    documented = documented_fields()
    prefixes = {f.rsplit(".", k)[0] for f in documented for k in range(1, f.count(".") + 1)}
    missing = result_fields(result, documented) - documented - prefixes
    if named_metrics:
        missing = {f for f in missing if not f.startswith("metrics.")}
    return sorted(missing)
