"""One run of a sweep, as a worker executes it: options in, one flat row out.

Owns: turning a RunSpec into ScenarioOptions, running it (no plots, no recording unless artifacts
are kept), and flattening its result into a row; a run that raises becomes an `error` row. Must not
know: pools, Ray, where rows are stored. Top-level functions only: process pools and Ray import it.
"""

from __future__ import annotations

import enum
import time
import traceback
from pathlib import Path
from typing import Any

from rescuemesh.experiments.spec import RunSpec


class RunStatus(str, enum.Enum):
    """How a run ended. A str enum so that rows stay plain data in Parquet and CSV."""

    SUCCESS = "success"  # ran; every criterion held
    FAILED = "failed"  # ran; a criterion did not hold (a result, not an error)
    ERROR = "error"  # the run raised: the row says what
    CRASHED = "crashed"  # the worker process died under it


#: Columns of a row that are not measured: what a row is, the same for the same configuration and seed.
KEY_COLUMNS = ("run_key", "scenario", "seed", "status", "success", "error")
#: Columns that depend on the machine, not on the run (left out when rows are compared).
WALL_CLOCK_COLUMNS = ("wall_time_s", "real_time_factor", "runtime.setup_s", "worker_s")


def scenario_options(spec: RunSpec):
    """ScenarioOptions for a run (the same fields `rescuemesh run` fills from its flags)."""
    from rescuemesh.geometry import Pose2D
    from rescuemesh.runtime import RadioKind
    from rescuemesh.scenarios import ScenarioOptions

    o = spec.option_dict()
    kwargs: dict[str, Any] = {"seed": spec.seed}
    if "loss" in o:
        kwargs["loss"] = o["loss"]
    if "relay" in o:
        kwargs["relay"] = o["relay"]
    if "radio" in o:
        kwargs["radio"] = RadioKind(o["radio"])
    if "robots" in o:
        kwargs["robots"] = o["robots"]
    if "radius" in o:
        kwargs["radius_m"] = o["radius"]
    if "outage" in o:
        kwargs["outage_s"] = o["outage"]
    if "secure" in o:
        kwargs["secure"] = o["secure"]
    if "time_limit" in o:
        kwargs["time_limit_s"] = o["time_limit"]
    if "goal" in o:
        kwargs["goal"] = Pose2D(*o["goal"], 0.0)
    return ScenarioOptions(**kwargs)


def mission_run(spec: RunSpec):
    """(ScenarioOptions, MissionScenario) for a run of a mission sweep: the mission's settings with
    the sweep's options over them."""
    from rescuemesh.experiments.mission import MissionScenario
    from rescuemesh.experiments.mission_spec import load_mission
    from rescuemesh.maps import load_map, office_map_path
    from rescuemesh.runtime import RadioKind

    mission = load_mission(Path(spec.mission_path))
    o = spec.option_dict()
    overrides = {"loss": o.get("loss"), "relay": o.get("relay"), "secure": o.get("secure"),
                 "time_limit_s": o.get("time_limit"), "radio": RadioKind(o["radio"]) if "radio" in o else None}
    options = MissionScenario.options_for(mission, spec.seed, **overrides)
    return options, MissionScenario(mission, options, load_map(mission.map_path or office_map_path()))


def execute(spec: RunSpec, artifacts: str | None = None) -> dict[str, Any]:
    """Run one configuration and seed; the row (never raises for the run's own errors)."""
    started = time.perf_counter()
    try:
        from rescuemesh.scenarios.runner import run_scenario

        out_dir = Path(artifacts) / spec.key if artifacts is not None else None
        if spec.mission_path is not None:
            options, scenario = mission_run(spec)
            outcome = run_scenario(None, options, scenario=scenario, out_dir=out_dir)
        else:
            outcome = run_scenario(spec.scenario, scenario_options(spec),
                                   map_path=Path(spec.map_path) if spec.map_path else None, out_dir=out_dir)
        row = row_from_result(spec, outcome.result)
    except Exception as error:  # a run's failure is a row, never the end of the sweep
        row = failed_row(spec, RunStatus.ERROR, f"{type(error).__name__}: {error}")
        row["traceback"] = traceback.format_exc(limit=8)
    row["worker_s"] = round(time.perf_counter() - started, 3)
    return row


def base_row(spec: RunSpec) -> dict[str, Any]:
    row: dict[str, Any] = {"run_key": spec.key, "scenario": spec.scenario, "seed": spec.seed}
    for name, value in spec.options:
        row[name] = value if not isinstance(value, list) else ",".join(f"{v:g}" for v in value)
    return row


def failed_row(spec: RunSpec, status: RunStatus, error: str) -> dict[str, Any]:
    return dict(base_row(spec), status=status.value, success=False, error=error)


def row_from_result(spec: RunSpec, result: dict[str, Any]) -> dict[str, Any]:
    """A flat row from result.json's content: configuration, seed, verdict, then every scalar of
    metrics, protocol, network and runtime as `section.name` columns (lists and per-robot tables
    are left out: they are in result.json when artifacts are kept)."""
    row = base_row(spec)
    row["status"] = (RunStatus.SUCCESS if result["success"] else RunStatus.FAILED).value
    row["success"] = bool(result["success"])
    row["error"] = None
    row["criteria_failed"] = "; ".join(c["check"] for c in result["criteria"] if not c["ok"]) or None
    for key in ("sim_time_s", "wall_time_s", "real_time_factor"):
        row[key] = result.get(key)
    for section in ("metrics", "protocol", "network"):
        _flatten(result.get(section, {}), section, row)
    setup = result.get("runtime", {}).get("setup_s")
    if setup is not None:
        row["runtime.setup_s"] = setup
    return row


def _flatten(value: Any, prefix: str, row: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(item, f"{prefix}.{key}", row)
    elif value is None or isinstance(value, (bool, int, float, str)):
        row[prefix] = value
    # lists (per-robot tables, event lists) are not columns
