"""The Python API for scripts and notebooks: `from rescuemesh import Mission, run, sweep`.

Owns: three small entry points over the mission engine, the scenario runner and the sweep engine,
and the result object `run` returns. Must not know: the command line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rescuemesh.experiments.mission_spec import Mission, load_mission


@dataclass(frozen=True)
class RunResult:
    """What one run gave: result.json's content (`result`), with its verdict at hand."""

    result: dict[str, Any]

    @property
    def success(self) -> bool:
        return bool(self.result["success"])

    @property
    def criteria(self) -> dict[str, bool]:
        return {c["check"]: c["ok"] for c in self.result["criteria"]}

    @property
    def metrics(self) -> dict[str, Any]:
        return self.result["metrics"]

    @property
    def protocol(self) -> dict[str, Any]:
        return self.result["protocol"]

    @property
    def network(self) -> dict[str, Any]:
        return self.result["network"]


def run(what: Mission | str | Path, *, seed: int = 0, loss: float | None = None, relay: bool | None = None,
        radio: str | None = None, out: str | Path | None = None, **scenario_options) -> RunResult:
    """Run a mission (a Mission, or a mission file's path) or a built-in scenario (its name) once.

    `loss`, `relay` and `radio` override the mission's settings (or the scenario's defaults); a
    built-in scenario also takes ScenarioOptions' other fields (`robots=10`, `radius_m=2.0`, ...).
    With `out`, result.json, the plots and run.mcap are written there as `rescuemesh run` does.
    Raises MissionError, ScenarioError or MapError (ValueErrors) for what cannot run."""
    from rescuemesh.runtime import RadioKind
    from rescuemesh.scenarios.runner import run_scenario

    overrides = {"loss": loss, "relay": relay, "radio": RadioKind(radio) if radio is not None else None}
    out_dir = Path(out) if out is not None else None
    if isinstance(what, Path) or (isinstance(what, str) and what.endswith((".yaml", ".yml"))):
        what = load_mission(Path(what))
    if isinstance(what, Mission):
        from rescuemesh.experiments.mission import MissionScenario
        from rescuemesh.maps import load_map, office_map_path

        if scenario_options:
            raise ValueError(f"a mission takes its team and script from its file, not {', '.join(scenario_options)}")
        options = MissionScenario.options_for(what, seed, **overrides)
        scenario = MissionScenario(what, options, load_map(what.map_path or office_map_path()))
        return RunResult(run_scenario(None, options, scenario=scenario, out_dir=out_dir).result)
    from rescuemesh.scenarios import ScenarioOptions

    options = ScenarioOptions(seed=seed, **{k: v for k, v in overrides.items() if v is not None}, **scenario_options)
    return RunResult(run_scenario(str(what), options, out_dir=out_dir).result)


def sweep(path: str | Path, out: str | Path, *, workers: int | None = None, ray: str | None = None,
          keep_artifacts: bool = False) -> list[dict[str, Any]]:
    """Run a sweep file (resuming what `out` already holds) and return every row (docs/sweeps.md)."""
    from rescuemesh.experiments.engine import load_rows, run_sweep
    from rescuemesh.experiments.executors import LocalPool, RayExecutor
    from rescuemesh.experiments.spec import load_sweep

    executor = RayExecutor(ray, workers) if ray else LocalPool(workers)
    summary = run_sweep(load_sweep(Path(path)), Path(out), executor, keep_artifacts=keep_artifacts)
    if summary.interrupted:
        raise KeyboardInterrupt
    return load_rows(Path(out))
