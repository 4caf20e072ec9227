"""The layer diagram (docs/design.md) as import-linter contracts in pyproject.toml, checked on the tree."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_import_contracts_hold(capsys):
    pytest.importorskip("importlinter")
    from importlinter.cli import lint_imports

    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True)
    out = capsys.readouterr().out
    assert code == 0, out
    assert "0 broken" in out


def test_a_broken_layer_is_caught(tmp_path, monkeypatch, capsys):
    """The contracts are not vacuous: a protocol module that imports the brain breaks them."""
    pytest.importorskip("importlinter")
    import shutil

    from importlinter.cli import lint_imports

    copy = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "rescuemesh", copy / "rescuemesh",
                    ignore=shutil.ignore_patterns("__pycache__", "data"))
    victim = copy / "rescuemesh" / "protocol" / "errors.py"
    victim.write_text(victim.read_text() + "\nimport rescuemesh.robot  # a layer broken on purpose\n")
    monkeypatch.syspath_prepend(str(copy))
    for name in [m for m in __import__("sys").modules if m == "rescuemesh" or m.startswith("rescuemesh.")]:
        monkeypatch.delitem(__import__("sys").modules, name)
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True)
    out = capsys.readouterr().out
    assert code != 0
    assert "rescuemesh.protocol.errors -> rescuemesh.robot" in out
