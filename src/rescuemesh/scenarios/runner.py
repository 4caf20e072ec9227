"""Run one scenario end to end: build the team, step until done or out of time, judge, report.

Owns: the run loop around a scenario and its wall-clock timing. Must not know: argument parsing.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.report import build_result, plot_timeline, plot_trajectories, write_result
from rescuemesh.runtime import SimRuntime
from rescuemesh.scenarios import ScenarioOptions, Verdict, get_scenario

#: How often the progress callback is called, in simulated seconds.
PROGRESS_PERIOD_S = 1.0


@dataclass
class RunOutcome:
    result: dict
    verdict: Verdict
    runtime: SimRuntime
    files: list[Path]


def run_scenario(name: str, options: ScenarioOptions, *, map_path: Path | None = None,
                 out_dir: Path | None = None,
                 progress: Callable[[float, float], None] | None = None) -> RunOutcome:
    """Run scenario `name`. Raises ScenarioError / MapError / ValueError for bad options."""
    cls = get_scenario(name)
    map_model: MapModel = load_map(map_path or office_map_path())
    scenario = cls(options, map_model)
    config = scenario.sim_config()
    wall_start = time.perf_counter()
    rt = SimRuntime(map_model, scenario.starts(), config)
    next_report = 0.0
    if progress:
        progress(rt.time, scenario.limit_s)
        next_report = PROGRESS_PERIOD_S
    while rt.time < scenario.limit_s:
        rt.step(scenario.tick)
        if progress and rt.time >= next_report:
            progress(rt.time, scenario.limit_s)
            next_report += PROGRESS_PERIOD_S
        if scenario.finished(rt):
            break
    wall_s = time.perf_counter() - wall_start
    verdict = scenario.evaluate(rt)
    if rt.time >= scenario.limit_s and not scenario.finished(rt):
        verdict.criteria.append((f"finished within the {scenario.limit_s:.0f} s limit", False))
        verdict.success = False
    result = build_result(scenario, rt, verdict, wall_s, map_model)
    files: list[Path] = []
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        files.append(write_result(result, out_dir / "result.json"))
        files.append(plot_trajectories(rt, map_model, out_dir / "trajectory.png",
                                       title=_title(scenario, verdict), metrics=verdict.metrics))
        files.append(plot_timeline(rt, out_dir / "timeline.png", title=_title(scenario, verdict),
                                   metrics=verdict.metrics))
        files.extend(scenario.write_files(rt, out_dir))
    return RunOutcome(result, verdict, rt, files)


def _title(scenario, verdict: Verdict) -> str:
    status = "success" if verdict.success else "FAILED"
    loss = f", loss {scenario.options.loss:g}" if scenario.options.loss else ""
    return f"rescuemesh {scenario.name} (seed {scenario.options.seed}{loss}): {status}"
