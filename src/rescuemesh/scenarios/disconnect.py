"""Scenario `disconnect`: during a Follow, robot_1's radio goes silent for `--outage` seconds from a
moment when robot_2 is moving (paper IV.A: "stop command execution in case of disconnecting and
failing to reconnect"). A short outage: robot_2 halts, the Follow resumes, both end in the far
room. A long one: both sides end the Follow FAILED (link lost) and robot_2 stays halted.

Owns: the outage script, its success criteria and metrics. Must not know: how the radio or the
world is simulated, how results are written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rescuemesh.protocol import MessageType, Reason, ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.scenarios.base import ScenarioError, Verdict, no_collisions
from rescuemesh.scenarios.follow import FollowScenario

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

DEFAULT_OUTAGE_S = 3.0
#: The outage starts once the follower moves at least this fast (m/s), at least this long (s)
#: after the Follow was accepted.
TRIGGER_SPEED, TRIGGER_AFTER_S = 0.2, 3.0
HALTED_SPEED = 0.02
#: robot_2 must halt within the link-loss timeout plus this (s) of the outage start (the issue).
HALT_MARGIN_S = 1.0
#: A long outage is watched this long (s) after it ends; robot_2 may drift at most DRIFT_M meanwhile.
WATCH_S, DRIFT_M = 3.0, 0.1


class DisconnectScenario(FollowScenario):
    name = "disconnect"
    summary = "during a Follow robot_1's radio is silent for --outage S; robot_2 halts, then resumes or both give up"
    time_limit_s = 150.0
    takes_outage = True

    def validate(self) -> None:
        super().validate()
        if not 0.0 < self.outage_s <= 600.0:
            raise ScenarioError(f"--outage must be in (0, 600] s, got {self.outage_s}")

    @property
    def outage_s(self) -> float:
        return self.options.outage_s if self.options.outage_s is not None else DEFAULT_OUTAGE_S

    @property
    def limit_s(self) -> float:
        return self.options.time_limit_s or max(self.time_limit_s, 60.0 + self.outage_s + WATCH_S)

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self.outage_start_s: float | None = None
        self.outage_end_s: float | None = None
        self._timings = None

    def link_loss_timeout_s(self, rt: SimRuntime) -> float:
        return rt.config.mesh.lost_after_seconds

    def expectation(self, rt: SimRuntime) -> str:
        """"resume", "fail" or "either": what the link-loss rule must do with this outage."""
        window = rt.config.brain.reconnect_window_s
        if self.outage_s <= window:
            return "resume"
        if self.outage_s >= self.link_loss_timeout_s(rt) + window + rt.config.mesh.heartbeat_period_s:
            return "fail"
        return "either"

    def tick(self, rt: SimRuntime) -> None:
        now = rt.time
        if self.outage_start_s is None:
            super().tick(rt)
            speed = rt.trajectories[self.follower][-1].speed
            if self.accepted_s is not None and now - self.accepted_s >= TRIGGER_AFTER_S and speed >= TRIGGER_SPEED:
                self.outage_start_s = now
                rt.set_radio(self.leader, False)
            return
        if self.outage_end_s is None and now >= self.outage_start_s + self.outage_s:
            self.outage_end_s = now
            rt.set_radio(self.leader, True)
        super().tick(rt)

    def finished(self, rt: SimRuntime) -> bool:
        if self.accepted_s is None:
            return super().finished(rt)
        if self.outage_end_s is None or rt.time < self.outage_end_s + WATCH_S:
            return False
        if self._follow_failed(rt, self.follower) and self._follow_failed(rt, self.leader):
            return True
        return super().finished(rt)

    def _follow_failed(self, rt: SimRuntime, name: str) -> bool:
        brain = rt.brain(name)
        if name == self.follower:
            return any(f.name == "follow" and f.result == ResultCode.FAILED and f.code == Reason.LINK_LOST
                       for f in brain.finished)
        return any(c.msg_type is MessageType.FOLLOW and c.result == ResultCode.FAILED and c.reason == Reason.LINK_LOST
                   for c in brain.outgoing.values())

    def evaluate(self, rt: SimRuntime) -> Verdict:
        samples = rt.trajectories[self.follower]
        start = self.outage_start_s
        halted = None
        if start is not None:
            halted = next((s.time_s for s in samples if s.time_s >= start and s.speed < HALTED_SPEED), None)
        timeout = self.link_loss_timeout_s(rt)
        halt_bound = timeout + HALT_MARGIN_S
        halt_after = None if halted is None or start is None else round(halted - start, 3)
        follower_failed = self._follow_failed(rt, self.follower)
        leader_failed = self._follow_failed(rt, self.leader)
        resumed = self._resumed(rt)
        expect = self.expectation(rt)
        criteria = [
            ("Follow confirmed ACCEPTED", self.accepted_s is not None),
            (f"robot_1's radio silent for {self.outage_s:g} s while robot_2 was moving", self.outage_end_s is not None),
            (f"robot_2 halted within {halt_bound:g} s of the outage start ({halt_after} s)",
             halt_after is not None and halt_after <= halt_bound),
        ]
        if expect in ("resume", "either") and not (expect == "either" and follower_failed):
            criteria.append(("the Follow resumed after the outage (no side gave it up)",
                             resumed and not follower_failed and not leader_failed))
            verdict = super().evaluate(rt)
            criteria += [c for c in verdict.criteria if c[0].startswith(("leader ends", "follower ends",
                                                                          "follower ends within"))]
        else:
            drift = self._drift_after_fail(rt)
            criteria += [
                ("robot_2 ended the Follow FAILED (link lost)", follower_failed),
                ("robot_1 ended the Follow FAILED (link lost)", leader_failed),
                (f"robot_2 stayed halted afterwards (drift {drift} m <= {DRIFT_M} m)",
                 drift is not None and drift <= DRIFT_M),
            ]
        criteria.append(no_collisions(rt))
        metrics = {
            "outage_s": self.outage_s,
            "outage_start_s": start,
            "outage_end_s": self.outage_end_s,
            "expected": expect,
            "link_loss_timeout_s": timeout,
            "reconnect_window_s": rt.config.brain.reconnect_window_s,
            "halted_after_s": halt_after,
            "link_lost_s": self._first(rt, self.follower, ev.LinkLost),
            "link_resumed_s": self._first(rt, self.follower, ev.LinkResumed),
            "follow_failed_link_lost": {"robot_1": leader_failed, "robot_2": follower_failed},
            "goal": [self.goal().x, self.goal().y],
            "halt_position": None if halted is None else _position_at(samples, halted),
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)

    def _resumed(self, rt: SimRuntime) -> bool:
        brain = rt.brain(self.follower)
        running = brain.running
        still = running is not None and running.behaviour.name == "follow" and running.started_s <= (self.outage_start_s or 0)
        ended_ok = any(f.name == "follow" and f.result != ResultCode.FAILED for f in brain.finished)
        return still or ended_ok

    def _drift_after_fail(self, rt: SimRuntime):
        failed = next((f.ended_s for f in rt.brain(self.follower).finished
                       if f.name == "follow" and f.code == Reason.LINK_LOST), None)
        if failed is None:
            return None
        after = [s.pose for s in rt.trajectories[self.follower] if s.time_s >= failed]
        return round(max(p.distance_to(after[0]) for p in after), 3) if after else None

    def _first(self, rt: SimRuntime, name: str, kind: type[ev.BrainEvent]):
        return next((e.time_s for e in rt.brain(name).log if isinstance(e, kind)), None)


def _position_at(samples, t):
    pose = next((s.pose for s in samples if s.time_s >= t), samples[-1].pose)
    return [round(pose.x, 3), round(pose.y, 3)]
