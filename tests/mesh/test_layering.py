"""mesh/ imports only the stdlib and rescuemesh.protocol, and keeps the house style."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import rescuemesh.mesh

PACKAGE = Path(rescuemesh.mesh.__file__).parent
BANNED = {"random", "time", "socket", "asyncio", "threading", "datetime", "numpy"}
#: Frame security uses the cryptography package (AES-CCM, HKDF). The fuzzer, which draws random
#: numbers and reads a clock, is a command outside the package (rescuemesh/checks/fuzz.py).
ALLOWED = {
    "security.py": {"cryptography"},
    "keys.py": {"cryptography"},
}


def imports(path: Path) -> list[str]:
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names.append(node.module)
    return names


def test_mesh_imports_only_the_stdlib_and_the_protocol():
    for path in PACKAGE.glob("*.py"):
        allowed = ALLOWED.get(path.name, set())
        for name in imports(path):
            top = name.split(".")[0]
            if top in allowed:
                continue
            assert top in sys.stdlib_module_names or name.startswith("rescuemesh.protocol"), (path.name, name)
            assert top not in BANNED, f"{path.name} imports {name}: no clock, randomness or I/O"


def test_modules_open_with_a_short_docstring_and_stay_small():
    for path in PACKAGE.glob("*.py"):
        text = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(text))
        assert doc and 2 <= len(doc.splitlines()) <= 3, path.name
        assert len(text.splitlines()) <= 400, path.name
