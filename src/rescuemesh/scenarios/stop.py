"""Scenario `stop`: during a Follow, robot_1 sends Stop; robot_2 must halt within 1 s of its arrival.

Owns: the Stop mission script, its success criteria and the stop-latency metric (paper IV-B).
Must not know: how the world is simulated or how results are written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rescuemesh.protocol import ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.scenarios.base import CommandRequest, Verdict, no_collisions
from rescuemesh.scenarios.follow import FollowScenario

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: Halted: odometry speed below this, in m/s.
HALTED_SPEED = 0.02
#: robot_2 must halt within this many seconds of the Stop frame's arrival (the issue's criterion).
MAX_STOP_LATENCY_S = 1.0
#: Send Stop once the follower has been moving at least this fast (m/s) after this time (s).
TRIGGER_SPEED, TRIGGER_AFTER_S = 0.2, 4.0
#: Watch the follower this long after Stop before ending (s); it must not move more than DRIFT_M.
WATCH_S, DRIFT_M = 4.0, 0.1


class StopScenario(FollowScenario):
    name = "stop"
    summary = "during a Follow, robot_1 sends Stop; robot_2 halts within 1 s of the frame's arrival"
    time_limit_s = 90.0

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._stop: CommandRequest | None = None
        self.stop_sent_s: float | None = None
        self.stop_result: ResultCode | None = None

    def tick(self, rt: SimRuntime) -> None:
        if self._stop is None:
            super().tick(rt)
            sample = rt.trajectories[self.follower][-1]
            if self.accepted_s is not None and rt.time >= TRIGGER_AFTER_S and sample.speed >= TRIGGER_SPEED:
                leader = rt.brain(self.leader)
                self._stop = CommandRequest(leader, self.follower, leader.command_stop)
                self.stop_sent_s = rt.time
        if self._stop is not None and self.stop_result is None:
            self.stop_result = self._stop.poll(rt.time)

    def finished(self, rt: SimRuntime) -> bool:
        if super().finished(rt) and self.accepted_s is None:  # the Follow was never confirmed
            return True
        if self._stop is not None and self._stop.given_up:
            return True
        return self.stop_sent_s is not None and rt.time >= self.stop_sent_s + WATCH_S and self.stop_result is not None

    def stop_arrival_s(self, rt: SimRuntime) -> float | None:
        if self.stop_sent_s is None:
            return None
        # Not an earlier automatic Stop (sent when a Follow was given up): the one this scenario sent.
        for event in rt.brain(self.follower).log:
            if isinstance(event, ev.Stopped) and event.time_s >= self.stop_sent_s:
                return event.time_s
        return None

    def evaluate(self, rt: SimRuntime) -> Verdict:
        arrival = self.stop_arrival_s(rt)
        samples = rt.trajectories[self.follower]
        halted = None
        if arrival is not None:
            halted = next((s.time_s for s in samples if s.time_s >= arrival and s.speed < HALTED_SPEED), None)
        latency = None if halted is None else round(halted - arrival, 3)
        drift = None
        if halted is not None:
            at_halt = next(s.pose for s in samples if s.time_s >= halted)
            drift = round(max(s.pose.distance_to(at_halt) for s in samples if s.time_s >= halted), 3)
        criteria = [
            ("Follow confirmed ACCEPTED", self.accepted_s is not None),
            ("Stop sent during the Follow, follower moving", self.stop_sent_s is not None),
            ("Stop confirmed DONE", self.stop_result == ResultCode.DONE),
            (f"follower halted within {MAX_STOP_LATENCY_S} s of the Stop's arrival",
             latency is not None and latency <= MAX_STOP_LATENCY_S),
            (f"follower stays put afterwards (drift <= {DRIFT_M} m)", drift is not None and drift <= DRIFT_M),
            no_collisions(rt),
        ]
        metrics = {
            "stop_sent_s": self.stop_sent_s,
            "stop_arrived_s": arrival,
            "halted_s": halted,
            "stop_latency_s": latency,
            "drift_after_stop_m": drift,
            "follower_speed_at_stop_mps": _speed_at(samples, arrival),
            "stop_position": _position_at(samples, arrival),
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def _position_at(samples, t):
    if t is None:
        return None
    pose = next((s.pose for s in samples if s.time_s >= t), samples[-1].pose)
    return [round(pose.x, 3), round(pose.y, 3)]


def _speed_at(samples, t):
    if t is None:
        return None
    return round(next((s.speed for s in samples if s.time_s >= t), samples[-1].speed), 3)
