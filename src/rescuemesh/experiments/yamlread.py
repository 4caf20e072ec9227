"""Reading a user's YAML file (a sweep, a mission) so that every error names the file and the line.

Owns: opening the file safely (regular file, size cap, UTF-8), composing it to a node tree with
PyYAML's safe loader, and the node walker that checks shapes. Must not know: what the keys mean.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


def read_yaml(path: Path, error: type[ValueError], max_bytes: int, what: str):
    """(Reader, root node) for `path`; `error` (one line, with file and line) if it cannot be read."""
    try:
        if not path.is_file():
            raise error(f"{path}: no such file" if not path.exists() else f"{path}: not a regular file")
        if path.stat().st_size > max_bytes:
            raise error(f"{path}: {path.stat().st_size} bytes; {what} is at most {max_bytes}")
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise error(f"{path}: not UTF-8 text") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f":{mark.line + 1}" if mark is not None else ""
        raise error(f"{path}{where}: not valid YAML: {exc.problem}") from None
    except (yaml.YAMLError, RecursionError) as exc:
        raise error(f"{path}: not valid YAML: {type(exc).__name__}") from None
    if root is None:
        raise error(f"{path}: the file is empty")
    return Reader(path, error), root


class Reader:
    """Walks the YAML node tree so that every error can name its line."""

    def __init__(self, path: Path, error: type[ValueError]) -> None:
        self.path, self.error = path, error

    def fail(self, node, message: str) -> ValueError:
        line = f":{node.start_mark.line + 1}" if node is not None else ""
        return self.error(f"{self.path}{line}: {message}")

    def mapping(self, node, what: str) -> dict[str, tuple[Any, Any]]:
        """A mapping node as {key: (key node, value node)}; keys must be unique strings."""
        if not isinstance(node, yaml.MappingNode):
            raise self.fail(node, f"{what} must be a mapping (key: value lines)")
        out: dict[str, tuple[Any, Any]] = {}
        for key_node, value_node in node.value:
            # a key's own text: YAML 1.1 reads a plain `on` as true, but `on:` here is the word
            if not isinstance(key_node, yaml.ScalarNode) or not key_node.value:
                raise self.fail(key_node, f"{what}: keys must be names")
            key = key_node.value
            if key in out:
                raise self.fail(key_node, f"{what}: {key!r} is given twice")
            out[key] = (key_node, value_node)
        return out

    def scalar(self, node) -> Any:
        if not isinstance(node, yaml.ScalarNode):
            raise self.fail(node, "expected a single value here, not a list or mapping")
        try:
            return yaml.constructor.SafeConstructor().construct_object(node, deep=True)
        except yaml.constructor.ConstructorError as error:
            raise self.fail(node, f"cannot read this value: {error.problem}") from None

    def sequence(self, node, what: str) -> list:
        if not isinstance(node, yaml.SequenceNode):
            raise self.fail(node, f"{what} must be a list ([a, b, ...])")
        if not node.value:
            raise self.fail(node, f"{what} is an empty list")
        return node.value

    def keys(self, node, what: str, allowed: dict[str, str], required: tuple[str, ...] = ()) -> dict[str, Any]:
        """A mapping whose keys must be among `allowed` (name -> what it is) and include `required`;
        {key: value node}."""
        fields = self.mapping(node, what)
        for key, (key_node, _) in fields.items():
            if key not in allowed:
                raise self.fail(key_node, f"{what}: unknown key {key!r}; expected one of: {', '.join(allowed)}")
        for key in required:
            if key not in fields:
                raise self.fail(node, f"{what}: missing {key!r} ({allowed[key]})")
        return {key: value for key, (_, value) in fields.items()}

    def number(self, node, what: str, *, minimum: float | None = None, above: float | None = None) -> float:
        value = self.scalar(node)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value or \
                value in (float("inf"), float("-inf")):
            raise self.fail(node, f"{what} must be a finite number, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.fail(node, f"{what} must be at least {minimum:g}, got {value!r}")
        if above is not None and value <= above:
            raise self.fail(node, f"{what} must be more than {above:g}, got {value!r}")
        return float(value)

    def whole(self, node, what: str, *, minimum: int = 0, maximum: int | None = None) -> int:
        value = self.scalar(node)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum or \
                (maximum is not None and value > maximum):
            top = "" if maximum is None else f" to {maximum}"
            raise self.fail(node, f"{what} must be a whole number from {minimum}{top}, got {value!r}")
        return value

    def text(self, node, what: str, choices: tuple[str, ...] | None = None) -> str:
        value = self.scalar(node)
        if not isinstance(value, str) or not value:
            raise self.fail(node, f"{what} must be a name, got {value!r}")
        if choices is not None and value not in choices:
            raise self.fail(node, f"{what} must be one of {', '.join(choices)}, got {value!r}")
        return value

    def flag(self, node, what: str) -> bool:
        value = self.scalar(node)
        if not isinstance(value, bool):
            raise self.fail(node, f"{what} must be true or false, got {value!r}")
        return value

    def point(self, node, what: str, *, yaw: bool = False) -> tuple[float, ...]:
        """[X, Y] in m (or [X, Y, YAW] with a yaw in rad, YAW optional, when `yaw`)."""
        shape = "[X, Y] or [X, Y, YAW]" if yaw else "[X, Y]"
        if not isinstance(node, yaml.SequenceNode) or len(node.value) not in ((2, 3) if yaw else (2,)):
            raise self.fail(node, f"{what} must be {shape} (m, rad)")
        values = tuple(self.number(item, what) for item in node.value)
        return values + (0.0,) * ((3 if yaw else 2) - len(values))

