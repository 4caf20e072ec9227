"""A sweep file: which scenario, which options held fixed, which axes vary, which seeds.

Owns: reading and validating `SWEEP.yaml` (every error names the file, the line and what was
expected), expanding the grid into runs, and each run's key (a hash of its whole configuration and
seed, so a finished run is recognised when a sweep is resumed). Must not know: how runs execute.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from rescuemesh.experiments.yamlread import Reader as _Reader, read_yaml

#: Longest sweep file read, in bytes: a grid is a few lines, not a data set.
MAX_FILE_BYTES = 256 * 1024
#: Most runs one sweep may hold (axes x seeds): a guard against a typo such as `seeds: 100000`.
MAX_RUNS = 100_000
#: Version of a row's meaning: part of every run key, so rows made by an older engine are redone.
ROW_VERSION = 1


class SweepError(ValueError):
    """A sweep file that cannot be run; the message is one line naming the file and the line."""


@dataclass(frozen=True)
class OptionSpec:
    """One scenario option a sweep may fix or vary: its YAML name, its type and its check."""

    name: str
    kind: str  # "float", "int", "bool", "choice", "pose", "text"
    help: str
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    below: float | None = None  # exclusive upper bound


#: The options of `rescuemesh run`, by their sweep-file names (docs/sweeps.md lists them).
OPTIONS: dict[str, OptionSpec] = {spec.name: spec for spec in (
    OptionSpec("loss", "float", "extra per-reception loss probability in [0, 1)", minimum=0.0, below=1.0),
    OptionSpec("relay", "bool", "robots relay frames (false: single-hop radio, as --no-relay)"),
    OptionSpec("radio", "choice", "radio channel model", choices=("ble", "disc")),
    OptionSpec("robots", "int", "team size, for scenarios that take one (convoy)", minimum=2),
    OptionSpec("radius", "float", "move-around radius in m", minimum=1e-9),
    OptionSpec("outage", "float", "disconnect: how long robot_1's radio is silent, in s", minimum=1e-9),
    OptionSpec("secure", "bool", "authenticated frames (false: CRC only, as --insecure)"),
    OptionSpec("time_limit", "float", "simulated seconds before the run gives up", minimum=1e-9),
    OptionSpec("goal", "pose", "the leader's goal X,Y in m"),
)}


#: Options a mission sweep may set (the rest is the mission file's).
MISSION_OPTIONS = ("loss", "relay", "radio", "secure", "time_limit")


@dataclass(frozen=True)
class PlotSpec:
    """One report plot: `y` (a row column) against axis `x`, one line per value of axis `lines`."""

    y: str
    x: str
    lines: str | None = None


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: the scenario, every option's value, the seed, and the key of all three."""

    scenario: str
    options: tuple[tuple[str, Any], ...]  # sorted (name, value) pairs, fixed and varied together
    seed: int
    map_path: str | None
    map_digest: str | None  # the map file's content hash (and the mission file's, for a mission sweep)
    key: str
    mission_path: str | None = None  # a mission file: the run is that mission (scenario is its name)

    def option_dict(self) -> dict[str, Any]:
        return dict(self.options)


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file."""

    name: str
    path: Path
    scenario: str
    fixed: dict[str, Any]
    axes: dict[str, list[Any]]
    seeds: list[int]
    map_path: Path | None
    metrics: list[str] = field(default_factory=list)
    plots: list[PlotSpec] = field(default_factory=list)
    mission_path: Path | None = None

    def _digest(self) -> str | None:
        parts = [_file_digest(p) for p in (self.map_path, self.mission_path) if p is not None]
        return "+".join(parts) or None

    @property
    def size(self) -> int:
        return math.prod(len(v) for v in self.axes.values()) * len(self.seeds)

    def runs(self) -> Iterator[RunSpec]:
        """Every combination of the axes' values, each for every seed (seeds innermost)."""
        digest = self._digest()
        mission = str(self.mission_path) if self.mission_path is not None else None
        names = list(self.axes)
        for values in itertools.product(*(self.axes[n] for n in names)):
            options = dict(self.fixed, **dict(zip(names, values)))
            pairs = tuple(sorted(options.items()))
            for seed in self.seeds:
                yield RunSpec(self.scenario, pairs, seed, str(self.map_path) if self.map_path else None, digest,
                              run_key(self.scenario, options, seed, digest), mission)

    def identity(self) -> str:
        """What makes two sweep files the same sweep (its grid, not its plots): a short hash."""
        text = json.dumps({"scenario": self.scenario, "fixed": self.fixed, "axes": self.axes, "seeds": self.seeds,
                           "map": self._digest()}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_key(scenario: str, options: dict[str, Any], seed: int, map_digest: str | None) -> str:
    """The key of one run: sha256 over its scenario, options, seed, map file and the row version."""
    text = json.dumps({"v": ROW_VERSION, "scenario": scenario, "options": options, "seed": seed, "map": map_digest},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


# --- reading ----------------------------------------------------------------------------------------

_TOP_KEYS = {"sweep": "the sweep's name", "scenario": "a built-in scenario (rescuemesh scenarios)",
             "mission": "a mission file (relative to the sweep file), instead of a scenario",
             "map": "a map file (relative to the sweep file)", "options": "options held fixed",
             "axes": "options that vary, each with a list of values", "seeds": "a count, a list, or {from, count}",
             "report": "what `rescuemesh report` shows: metrics and plots"}


def load_sweep(path: Path) -> Sweep:
    """Read and validate a sweep file; SweepError (one line, with file and line) if anything is off."""
    path = Path(path)
    reader, root = read_yaml(path, SweepError, MAX_FILE_BYTES, "a sweep file")
    top = reader.mapping(root, "a sweep file")
    for key, (key_node, _) in top.items():
        if key not in _TOP_KEYS:
            raise reader.fail(key_node, f"unknown key {key!r}; expected one of: {', '.join(_TOP_KEYS)}")
    for required in ("axes", "seeds"):
        if required not in top:
            raise reader.fail(root, f"missing {required!r} ({_TOP_KEYS[required]})")
    if ("scenario" in top) == ("mission" in top):
        raise reader.fail(root, "a sweep names either a `scenario` (built in) or a `mission` (a file), not both")

    from rescuemesh.scenarios import SCENARIOS  # the registry only; imports no simulator

    mission_path = None
    if "mission" in top:
        from rescuemesh.experiments.mission_spec import MissionError, load_mission

        mission_node = top["mission"][1]
        mission_path = (path.parent / str(reader.scalar(mission_node))).resolve()
        try:
            scenario = load_mission(mission_path).name
        except MissionError as error:
            raise reader.fail(mission_node, f"its mission: {error}") from None
        if "map" in top:
            raise reader.fail(top["map"][0], "a mission names its own map")
    else:
        scenario_node = top["scenario"][1]
        scenario = reader.scalar(scenario_node)
        if scenario not in SCENARIOS:
            raise reader.fail(scenario_node, f"unknown scenario {scenario!r}; known: {', '.join(SCENARIOS)}")
    name = str(reader.scalar(top["sweep"][1])) if "sweep" in top else path.stem
    map_path = None
    if "map" in top:
        map_node = top["map"][1]
        map_path = (path.parent / str(reader.scalar(map_node))).resolve()
        if not map_path.is_file():
            raise reader.fail(map_node, f"map file {str(map_path)!r} does not exist")

    fixed = {}
    if "options" in top:
        for key, (key_node, value_node) in reader.mapping(top["options"][1], "options").items():
            fixed[key] = _option_value(reader, key, key_node, value_node)
    axes: dict[str, list[Any]] = {}
    for key, (key_node, value_node) in reader.mapping(top["axes"][1], "axes").items():
        if key in fixed:
            raise reader.fail(key_node, f"{key!r} is both held fixed (options) and varied (axes)")
        values = [_option_value(reader, key, key_node, item) for item in reader.sequence(value_node, f"axis {key!r}")]
        if len(set(map(json.dumps, values))) != len(values):
            raise reader.fail(value_node, f"axis {key!r} lists a value twice")
        axes[key] = values
    if not axes:
        raise reader.fail(top["axes"][1], "axes is empty: vary at least one option")
    seeds = _seeds(reader, top["seeds"][1])
    size = math.prod(len(v) for v in axes.values()) * len(seeds)
    if size > MAX_RUNS:
        raise reader.fail(root, f"the grid has {size} runs; a sweep holds at most {MAX_RUNS}")
    metrics, plots = _report(reader, top["report"][1], axes) if "report" in top else ([], [])
    if mission_path is not None:
        for key, (key_node, _) in [*reader.mapping(top["axes"][1], "axes").items(),
                                   *(reader.mapping(top["options"][1], "options").items() if "options" in top else [])]:
            if key not in MISSION_OPTIONS:
                raise reader.fail(key_node, f"{key!r} is not a mission setting; a mission sweep may set: "
                                            f"{', '.join(MISSION_OPTIONS)}")
    return Sweep(name, path, scenario, fixed, axes, seeds, map_path, metrics, plots, mission_path)


def _option_value(reader: _Reader, key: str, key_node, node) -> Any:
    spec = OPTIONS.get(key)
    if spec is None:
        raise reader.fail(key_node, f"unknown option {key!r}; a sweep may set: {', '.join(OPTIONS)}")
    if spec.kind == "pose":
        items = reader.sequence(node, f"{key}")
        values = [reader.scalar(item) for item in items]
        if len(values) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                       for v in values):
            raise reader.fail(node, f"{key} must be [X, Y] in m (two finite numbers)")
        return [float(v) for v in values]
    value = reader.scalar(node)
    if spec.kind == "bool":
        if not isinstance(value, bool):
            raise reader.fail(node, f"{key} must be true or false, got {value!r}")
        return value
    if spec.kind == "choice":
        if value not in spec.choices:
            raise reader.fail(node, f"{key} must be one of {', '.join(spec.choices)}, got {value!r}")
        return value
    if spec.kind == "int":
        if not isinstance(value, int) or isinstance(value, bool):
            raise reader.fail(node, f"{key} must be a whole number, got {value!r}")
    elif spec.kind == "float":
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise reader.fail(node, f"{key} must be a finite number, got {value!r}")
        value = float(value)
    if spec.minimum is not None and value < spec.minimum:
        raise reader.fail(node, f"{key} must be at least {spec.minimum:g}, got {value!r}")
    if spec.below is not None and value >= spec.below:
        raise reader.fail(node, f"{key} must be below {spec.below:g}, got {value!r}")
    return value


def _seeds(reader: _Reader, node) -> list[int]:
    def seed(item_node, value) -> int:
        if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < 2**63:
            raise reader.fail(item_node, f"a seed is a whole number from 0 to 2**63 - 1, got {value!r}")
        return value

    if isinstance(node, yaml.ScalarNode):
        count = seed(node, reader.scalar(node))
        if count < 1:
            raise reader.fail(node, "seeds: a count must be at least 1")
        return list(range(count))
    if isinstance(node, yaml.MappingNode):
        fields = reader.mapping(node, "seeds")
        unknown = set(fields) - {"from", "count"}
        if unknown or "count" not in fields:
            raise reader.fail(node, "seeds as a mapping takes `from` (default 0) and `count`")
        first = seed(fields["from"][1], reader.scalar(fields["from"][1])) if "from" in fields else 0
        count = seed(fields["count"][1], reader.scalar(fields["count"][1]))
        if count < 1:
            raise reader.fail(fields["count"][1], "seeds: count must be at least 1")
        return list(range(first, first + count))
    values = [seed(item, reader.scalar(item)) for item in reader.sequence(node, "seeds")]
    if len(set(values)) != len(values):
        raise reader.fail(node, "seeds lists a seed twice")
    return values


def _report(reader: _Reader, node, axes: dict[str, list[Any]]) -> tuple[list[str], list[PlotSpec]]:
    fields = reader.mapping(node, "report")
    unknown = set(fields) - {"metrics", "plots"}
    if unknown:
        raise reader.fail(fields[sorted(unknown)[0]][0], f"report takes `metrics` and `plots`, not {sorted(unknown)[0]!r}")
    metrics = []
    if "metrics" in fields:
        for item in reader.sequence(fields["metrics"][1], "report.metrics"):
            value = reader.scalar(item)
            if not isinstance(value, str) or not value:
                raise reader.fail(item, "a metric is a row column such as protocol.delivery_ratio")
            metrics.append(value)
    plots = []
    if "plots" in fields:
        for item in reader.sequence(fields["plots"][1], "report.plots"):
            plot = reader.mapping(item, "a plot")
            unknown = set(plot) - {"x", "y", "lines"}
            if unknown or "x" not in plot or "y" not in plot:
                raise reader.fail(item, "a plot takes `y` (a column), `x` (an axis) and optionally `lines` (an axis)")
            x, y = reader.scalar(plot["x"][1]), reader.scalar(plot["y"][1])
            lines = reader.scalar(plot["lines"][1]) if "lines" in plot else None
            for what, axis in (("x", x), ("lines", lines)):
                if axis is not None and axis not in axes:
                    raise reader.fail(plot[what][1], f"plot {what} {axis!r} is not an axis; axes: {', '.join(axes)}")
            plots.append(PlotSpec(str(y), x, lines))
    return metrics, plots
