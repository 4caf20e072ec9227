"""The episode: a team built in one process or as processes, stepped until its task is finished or out
of time, optionally paced to the wall clock (as dm_control's composer Environment owns its loop and a
task implements hooks).

Owns: building the runtime for a run and the loop. Must not know: what a task checks, results, plots.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.processes.spawn import ProcessOptions

if TYPE_CHECKING:
    from rescuemesh.geometry import Pose2D
    from rescuemesh.maps import MapModel

#: How often the progress callback is called, in simulated seconds.
PROGRESS_PERIOD_S = 1.0


class EpisodeTask(Protocol):
    """The hooks an episode calls: `tick` once per control step (give commands, watch the robots),
    `finished` after it; `limit_s` ends the episode in simulated time."""

    limit_s: float

    def tick(self, rt) -> None: ...
    def finished(self, rt) -> bool: ...


class StepObserver(Protocol):
    """Called after every step (a recorder)."""

    def tick(self) -> None: ...


@dataclass(frozen=True)
class EpisodeTiming:
    """Wall time: building the runtime (world built, robots joined) and the whole episode from the start."""

    setup_s: float
    wall_s: float


def build_runtime(map_model: MapModel, starts: Mapping[str, Pose2D], config: SimConfig,
                  processes: ProcessOptions | None, cleanup: ExitStack, *, team_key: bytes | None = None,
                  log_dir: Path | None = None):
    """The one-process runtime, or a world with its robots in processes (closed by `cleanup`); with
    processes that are spawned here, their logs go to `log_dir` (a temporary folder when None)."""
    if processes is None:
        from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

        return SimRuntime(map_model, dict(starts), config)
    from rescuemesh.runtime.processes.process_world import ProcessRuntime, WorldHost, world_control_key
    from rescuemesh.runtime.processes.spawn import ControlCarrier, RobotProcesses, free_endpoint

    over_pipes = processes.spawn and processes.control is ControlCarrier.PIPES
    listen = None if over_pipes else processes.listen or free_endpoint()
    team = processes.team
    if processes.spawn and team is None:
        log_dir = log_dir if log_dir is not None else Path(cleanup.enter_context(tempfile.TemporaryDirectory()))
        team = RobotProcesses(listen, processes.run_id, log_dir, key_file=processes.key_file,
                              control=processes.control)
    if processes.spawn and team.control is not processes.control:
        raise ValueError(f"robot processes started over {team.control.value}, the run's control plane is "
                         f"{processes.control.value}")
    control_key = world_control_key(team_key, team.control_key if processes.spawn else None)
    if over_pipes:
        from rescuemesh.runtime.processes.pipes import PipeHost

        host = PipeHost(team.channels, control_key, log_dir=team.log_dir)
    else:
        host = WorldHost(listen, processes.run_id, control_key=control_key)
    cleanup.callback(host.close)
    if processes.spawn:
        cleanup.callback(team.close)
        for name in starts:
            if name not in team.procs:
                team.start(name)
    rt = ProcessRuntime(map_model, dict(starts), config, host, key_from_seed=team_key is None,
                        join_timeout_s=processes.join_timeout_s)
    cleanup.callback(rt.close)
    return rt


def run_episode(task: EpisodeTask, rt, *, started_s: float, observer: StepObserver | None = None,
                progress: Callable[[float, float], None] | None = None, realtime: bool = False) -> float:
    """Step `rt` with `task` until it is finished or `task.limit_s` is reached; return the wall time in s
    since `started_s` (a time.perf_counter() reading). With `realtime`, simulated time is held to the
    wall clock from `started_s`; `progress(time, limit)` is called every PROGRESS_PERIOD_S."""
    next_report = 0.0
    if progress:
        progress(rt.time, task.limit_s)
        next_report = PROGRESS_PERIOD_S
    while rt.time < task.limit_s:
        rt.step(task.tick)
        if observer is not None:
            observer.tick()
        if progress and rt.time >= next_report:
            progress(rt.time, task.limit_s)
            next_report += PROGRESS_PERIOD_S
        if task.finished(rt):
            break
        if realtime:
            time.sleep(max(0.0, started_s + rt.time - time.perf_counter()))
    return time.perf_counter() - started_s
