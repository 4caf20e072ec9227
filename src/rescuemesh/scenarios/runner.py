"""Run one scenario end to end: the runtime builds the team and steps the episode (runtime/episode.py);
this judges it and writes its results.

Owns: a scenario's run from options to result.json and plots. Must not know: argument parsing.
"""

from __future__ import annotations

import time
import os
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.report import build_result, plot_timeline, plot_trajectories, write_result
from rescuemesh.runtime import SimRuntime
from rescuemesh.runtime.episode import build_runtime, run_episode
from rescuemesh.runtime.processes.spawn import ProcessOptions
from rescuemesh.scenarios import Scenario, ScenarioError, ScenarioOptions, Verdict, get_scenario


@dataclass
class RunOutcome:
    result: dict
    verdict: Verdict
    runtime: SimRuntime
    files: list[Path]


def run_scenario(name: str | None, options: ScenarioOptions, *, map_path: Path | None = None,
                 out_dir: Path | None = None,
                 progress: Callable[[float, float], None] | None = None,
                 processes: ProcessOptions | None = None, realtime: bool = False,
                 live_port: int | None = None, scenario: Scenario | None = None, rosbag: bool = False) -> RunOutcome:
    """Run scenario `name`. Raises ScenarioError / MapError / ValueError for bad options (a `live_port`
    that cannot be served too). With `out_dir`, the run is recorded to `out_dir/run.mcap`; with
    `live_port`, the same channels are served on ws://127.0.0.1:live_port during the run.
    `scenario`: the scenario already built from `name`, `options` and the map (neither is built
    again: `run --processes` needs its robots' names before the world is built); with `name` None,
    a scenario built from a mission file, run as it is."""
    if name is None:  # a scenario built elsewhere (a mission file): run as given
        if scenario is None or scenario.options is not options:
            raise ValueError("without a scenario name, give the scenario built with these options")
        cls = type(scenario)
    else:
        cls = get_scenario(name)
    if scenario is None:
        scenario = cls(options, load_map(map_path or office_map_path()))
    elif type(scenario) is not cls or scenario.options is not options:
        raise ValueError(f"the scenario given was not built as {name!r} with these options")
    map_model = scenario.map
    config = scenario.sim_config()
    if processes is not None and not cls.runs_as_processes:
        from rescuemesh.scenarios import SCENARIOS

        able = ", ".join(n for n, c in SCENARIOS.items() if c.runs_as_processes)
        raise ScenarioError(f"scenario {name} does not run with --processes yet (these do: {able})")
    wall_start = time.perf_counter()
    with ExitStack() as cleanup:
        log_dir = out_dir / "processes" if out_dir is not None else None
        rt = build_runtime(map_model, scenario.starts(), config, processes, cleanup,
                           team_key=scenario.options.team_key, log_dir=log_dir)
        setup_s = time.perf_counter() - wall_start  # world built, robots joined
        recorder = _recorder(rt, map_model, out_dir, live_port, cleanup, rosbag=rosbag)
        wall_s = run_episode(scenario, rt, started_s=wall_start, observer=recorder, progress=progress,
                             realtime=realtime)
        verdict, result = _judge(scenario, rt, wall_s, map_model)
        result["runtime"]["setup_s"] = round(setup_s, 3)
        files: list[Path] = []
        if out_dir is not None:  # before the robots leave: plots read their logs
            out_dir.mkdir(parents=True, exist_ok=True)
            files.append(write_result(result, out_dir / "result.json"))
            files.append(plot_trajectories(rt, map_model, out_dir / "trajectory.png",
                                           title=_title(scenario, verdict), metrics=verdict.metrics,
                                           goal_label=scenario.goal_label))
            files.append(plot_timeline(rt, out_dir / "timeline.png", title=_title(scenario, verdict),
                                       metrics=verdict.metrics))
            files.extend(scenario.write_files(rt, out_dir))
            files.append(recorder.finish())
    return RunOutcome(result, verdict, rt, files)


def _recorder(rt, map_model, out_dir: Path | None, live_port: int | None, cleanup: ExitStack, *,
              rosbag: bool = False):
    """The run's recorder (run.mcap in `out_dir`, the live server, with `rosbag` the rosbag2 folder
    run.rosbag2 in `out_dir`), closed by `cleanup`; None for neither."""
    if out_dir is None and live_port is None:
        return None
    from rescuemesh.report.recording import RunRecorder  # imports foxglove-sdk: only when recording

    recorder = RunRecorder(rt, map_model, out_dir / "run.mcap" if out_dir is not None else None, live_port=live_port,
                           rosbag=out_dir / "run.rosbag2" if rosbag and out_dir is not None else None)
    cleanup.callback(recorder.close)
    return recorder


def _judge(scenario, rt, wall_s: float, map_model) -> tuple[Verdict, dict]:
    """The verdict and result.json's content, while the robots (maybe processes) are still there."""
    verdict = scenario.evaluate(rt)
    if rt.time >= scenario.limit_s and not scenario.finished(rt):
        verdict.criteria.append((f"finished within the {scenario.limit_s:.0f} s limit", False))
        verdict.success = False
    result = build_result(scenario, rt, verdict, wall_s, map_model)
    if hasattr(rt, "processes"):
        result["runtime"] = {"kind": "processes", "processes": rt.processes(),
                             "process_events": [[t, robot, what] for t, robot, what in rt.process_log],
                             "control_plane": rt.control_plane()}
    else:
        result["runtime"] = {"kind": "one process",
                             "processes": [{"name": "world and robots", "pid": os.getpid(),
                                            "cpu_s": round(time.process_time(), 3)}]}
    # the loop's wall time by part: world (physics, sensors), medium, robots (SimRuntime.wall_s)
    result["runtime"]["wall_s_by_part"] = {part: round(s, 3) for part, s in getattr(rt, "wall_s", {}).items()}
    return verdict, result


def _title(scenario, verdict: Verdict) -> str:
    status = "success" if verdict.success else "FAILED"
    loss = f", loss {scenario.options.loss:g}" if scenario.options.loss else ""
    return f"rescuemesh {scenario.name} (seed {scenario.options.seed}{loss}): {status}"
