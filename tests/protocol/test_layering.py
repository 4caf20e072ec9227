"""protocol/ imports only the allowed stdlib modules and itself (docs/design.md)."""

from __future__ import annotations

import ast
from pathlib import Path

import rescuemesh.protocol

ALLOWED = {"__future__", "struct", "zlib", "enum", "dataclasses", "collections", "typing", "abc", "math",
           "functools"}  # functools: lru_cache, the memory of codec.decode_frame
PACKAGE = Path(rescuemesh.protocol.__file__).parent


def test_protocol_imports_only_the_stdlib_allow_list_and_itself():
    for path in PACKAGE.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level > 0:  # relative: the package itself
                    continue
                names = [node.module]
            else:
                continue
            for name in names:
                assert name.split(".")[0] in ALLOWED, f"{path.name} imports {name}"


def test_modules_open_with_a_short_docstring_and_stay_small():
    for path in PACKAGE.glob("*.py"):
        text = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(text))
        assert doc and 2 <= len(doc.splitlines()) <= 3, path.name
        assert len(text.splitlines()) <= 400, path.name


def test_the_public_surface_is_the_documented_list_and_every_name_resolves():
    # this used to be 70 names, constants and internals among them (issue 18 item 4)
    doc = (PACKAGE.parents[2] / "docs" / "protocol.md").read_text(encoding="utf-8")
    section = doc.split("## The Python surface", 1)[1].split("\n## ", 1)[0]
    documented = [line[3:-1] for line in section.splitlines() if line.startswith("- `")]
    assert sorted(rescuemesh.protocol.__all__) == sorted(documented)
    assert len(documented) <= 30
    for name in rescuemesh.protocol.__all__:
        assert getattr(rescuemesh.protocol, name) is not None, name
    public = {n for n in vars(rescuemesh.protocol) if not n.startswith("_")}
    modules = {n for n in public if type(getattr(rescuemesh.protocol, n)).__name__ == "module"}
    assert public - modules == set(rescuemesh.protocol.__all__)
