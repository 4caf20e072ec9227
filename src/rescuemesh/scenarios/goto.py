"""Scenarios `goto` and `return` (paper Table III): robot_1 sends robot_2 a Goto for a pose in another
room, and robot_2 reports progress, then DONE; in `return` robot_2 is then told Return and drives
back to its base. Owns the two missions, their criteria and metrics. Must not know the simulator.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import MessageType, ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.scenarios.base import CommandRequest, Scenario, ScenarioError, Verdict, no_collisions

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: Where robot_2 is sent on the office: room_south, east of its table, facing north.
OFFICE_GOTO = Pose2D(12.6, 2.4, math.pi / 2)
XY_TOLERANCE_M, YAW_TOLERANCE_RAD = 0.15, 0.3
#: The map's named goal (map YAML `goals:`) robot_2 is sent to when no --goal is given.
MAP_GOAL = "goto"


def _pose_at(samples, time_s: float | None) -> Pose2D:
    """The pose of the first trajectory sample at or after `time_s` (the last one for None or later)."""
    if time_s is not None:
        for sample in samples:
            if sample.time_s >= time_s:
                return sample.pose
    return samples[-1].pose


def _angle(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


class GotoScenario(Scenario):
    name = "goto"
    runs_as_processes = True
    takes_goal = True
    summary = "robot_1 sends robot_2 a Goto for a pose in another room; progress, then DONE at the pose"
    time_limit_s = 120.0
    sender, mover = "robot_1", "robot_2"
    goal_label = "robot_2's Goto target"

    def mission_point(self) -> Pose2D:
        return self.goal()

    def goal(self) -> Pose2D:
        if self.options.goal is not None:
            return self.options.goal
        if self.on_office:
            return OFFICE_GOTO
        if MAP_GOAL in self.map.goals:
            return self.map.goals[MAP_GOAL]
        raise ScenarioError(f"map {self.map.name!r} has no default Goto pose (goals: {MAP_GOAL}): "
                            f"give --goal X,Y[,YAW]")

    def validate(self) -> None:
        self.require_free("goal", self.goal())

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._goto: CommandRequest | None = None
        self.goto_done_s: float | None = None

    @staticmethod
    def _outcome(rt: SimRuntime, request: CommandRequest | None):
        """The confirmed copy of a request: its OutgoingCommand, or None."""
        return None if request is None else request.confirmed()

    def tick(self, rt: SimRuntime) -> None:
        brain = rt.brain(self.sender)
        if self._goto is None:
            self._goto = CommandRequest(brain, self.mover, lambda peer, now: brain.command_goto(peer, self.goal(), now))
        self._goto.poll(rt.time)
        sent = self._outcome(rt, self._goto)
        if self.goto_done_s is None and sent is not None and sent.result == ResultCode.DONE:
            self.goto_done_s = rt.time

    def finished(self, rt: SimRuntime) -> bool:
        sent = self._outcome(rt, self._goto)
        return self.goto_done_s is not None or (sent is not None and sent.result in (
            ResultCode.FAILED, ResultCode.CANCELLED, ResultCode.DENIED, ResultCode.UNSUPPORTED)) \
            or (self._goto is not None and self._goto.given_up)

    def _progress_reports(self, rt: SimRuntime) -> int:
        return sum(1 for e in rt.brain(self.sender).log if isinstance(e, ev.Confirm)
                   and e.command is MessageType.GOTO and e.result is ResultCode.IN_PROGRESS)

    def evaluate(self, rt: SimRuntime) -> Verdict:
        goal = self.goal()
        # the Goto's own error: where the mover was when DONE arrived (the run's end without one)
        end = _pose_at(rt.trajectories[self.mover], self.goto_done_s)
        error_m, error_rad = end.distance_to(goal), _angle(end.yaw, goal.yaw)
        sent = self._outcome(rt, self._goto)
        reports = self._progress_reports(rt)
        criteria = [
            ("Goto confirmed DONE", sent is not None and sent.result == ResultCode.DONE),
            (f"robot_2 within {XY_TOLERANCE_M} m and {YAW_TOLERANCE_RAD} rad of the pose "
             f"({error_m:.3f} m, {error_rad:.3f} rad)", error_m <= XY_TOLERANCE_M and error_rad <= YAW_TOLERANCE_RAD),
            (f"progress reports seen ({reports})", reports >= 1),
            no_collisions(rt),
        ]
        metrics = {
            "goal": [goal.x, goal.y],
            "goal_region": self.map.region_of(goal.x, goal.y),
            "goto_done_s": self.goto_done_s,
            "final_error_m": round(error_m, 3),
            "final_yaw_error_rad": round(error_rad, 3),
            "progress_reports": reports,
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


class ReturnScenario(GotoScenario):
    name = "return"
    summary = "robot_2 is sent away with Goto, then told Return: it drives back to its base"
    time_limit_s = 200.0

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._return: CommandRequest | None = None
        self.return_done_s: float | None = None

    def tick(self, rt: SimRuntime) -> None:
        super().tick(rt)
        if self.goto_done_s is None:
            return
        brain = rt.brain(self.sender)
        if self._return is None:
            self._return = CommandRequest(brain, self.mover, brain.command_return)
        self._return.poll(rt.time)
        sent = self._outcome(rt, self._return)
        if self.return_done_s is None and sent is not None and sent.result == ResultCode.DONE:
            self.return_done_s = rt.time

    def finished(self, rt: SimRuntime) -> bool:
        if self.goto_done_s is None:
            return super().finished(rt)
        sent = self._outcome(rt, self._return)
        return self.return_done_s is not None or (sent is not None and sent.result in (
            ResultCode.FAILED, ResultCode.CANCELLED, ResultCode.DENIED)) or (
            self._return is not None and self._return.given_up)

    def evaluate(self, rt: SimRuntime) -> Verdict:
        away = super().evaluate(rt)
        base = self.map.bases.get(self.mover, rt.trajectories[self.mover][0].pose)  # as the runtime sets it
        end = rt.trajectories[self.mover][-1].pose
        error_m, error_rad = end.distance_to(base), _angle(end.yaw, base.yaw)
        sent = self._outcome(rt, self._return)
        criteria = [away.criteria[0],
                    ("Return confirmed DONE", sent is not None and sent.result == ResultCode.DONE),
                    (f"robot_2 back at its base within {XY_TOLERANCE_M} m and {YAW_TOLERANCE_RAD} rad "
                     f"({error_m:.3f} m, {error_rad:.3f} rad)",
                     error_m <= XY_TOLERANCE_M and error_rad <= YAW_TOLERANCE_RAD),
                    no_collisions(rt)]
        metrics = {k: v for k, v in away.metrics.items() if k not in ("final_error_m", "final_yaw_error_rad")}
        # final_error_m is the Return's own (this used to be the Goto's error measured after the
        # robot had gone home); the Goto's is goto_error_m, taken when its DONE arrived
        metrics.update(goto_error_m=away.metrics["final_error_m"],
                       goto_yaw_error_rad=away.metrics["final_yaw_error_rad"],
                       base=[round(base.x, 3), round(base.y, 3)], return_done_s=self.return_done_s,
                       final_error_m=round(error_m, 3), final_yaw_error_rad=round(error_rad, 3))
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)
