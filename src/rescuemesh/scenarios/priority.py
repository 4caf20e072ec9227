"""Scenario `priority` (the paper's "checks incoming messages for command with higher priority"):
robot_2 follows robot_1, a team lead; robot_3, a peer, sends robot_2 a Goto and is
TEMPORARILY_REJECTED; then robot_4, the operator station, sends a Goto that preempts the Follow,
and robot_1 gets CANCELLED with the reason. Owns the script and its criteria; not the simulator.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import replace

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.robot import BrainConfig
from rescuemesh.robot.policy import Rank
from rescuemesh.runtime import SimConfig
from rescuemesh.scenarios.base import CommandRequest, Scenario, Verdict, no_collisions

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

RANKS = {1: Rank.TEAM_LEAD, 2: Rank.PEER, 3: Rank.PEER, 4: Rank.OPERATOR}
#: The operator station stands in the hall's south-west corner (a robot that does not move).
OFFICE_STATION = Pose2D(1.2, 1.2, 0.0)
PEER_GOTO = Pose2D(3.0, 7.5, 0.0)
OPERATOR_GOTO = Pose2D(4.0, 2.5, 0.0)
#: Seconds of following before the peer asks, and between the peer's answer and the operator's Goto.
PEER_AFTER_S, OPERATOR_AFTER_S = 3.0, 1.0


class PriorityScenario(Scenario):
    name = "priority"
    runs_as_processes = True
    summary = "a peer's Goto is TEMPORARILY_REJECTED during a team lead's Follow; the operator's preempts it"
    time_limit_s = 90.0
    robots = ("robot_1", "robot_2", "robot_3", "robot_4")
    idle_robots = ()
    office_extra_starts = {"robot_4": (OFFICE_STATION, "the operator station")}

    def sim_config(self) -> SimConfig:
        return replace(super().sim_config(), brain=BrainConfig(ranks=RANKS))

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._follow = self._peer = self._operator = None
        self.follow_accepted_s = self.peer_answered_s = self.operator_answered_s = None

    @staticmethod
    def _result(rt: SimRuntime, name: str, request: CommandRequest | None):
        return None if request is None else request.confirmed()

    def tick(self, rt: SimRuntime) -> None:
        now = rt.time
        lead, peer, station = rt.brain("robot_1"), rt.brain("robot_3"), rt.brain("robot_4")
        if self._follow is None:
            self._follow = CommandRequest(lead, "robot_2", lead.command_follow)
        if self.follow_accepted_s is None:
            if self._follow.poll(now) == ResultCode.ACCEPTED:
                self.follow_accepted_s = now
            return
        if self._peer is None and now >= self.follow_accepted_s + PEER_AFTER_S:
            self._peer = CommandRequest(peer, "robot_2", lambda p, t: peer.command_goto(p, PEER_GOTO, t))
        if self._peer is not None and self.peer_answered_s is None:
            if self._peer.poll(now) is not None:
                self.peer_answered_s = now
        if self.peer_answered_s is not None and self._operator is None \
                and now >= self.peer_answered_s + OPERATOR_AFTER_S:
            self._operator = CommandRequest(station, "robot_2", lambda p, t: station.command_goto(p, OPERATOR_GOTO, t))
        if self._operator is not None and self.operator_answered_s is None:
            if self._operator.poll(now) is not None:
                self.operator_answered_s = now

    def finished(self, rt: SimRuntime) -> bool:
        if self.operator_answered_s is None:
            return any(r is not None and r.given_up for r in (self._follow, self._peer, self._operator))
        follow = self._result(rt, "robot_1", self._follow)
        return follow is not None and follow.result != ResultCode.ACCEPTED and rt.time >= self.operator_answered_s + 2.0

    def evaluate(self, rt: SimRuntime) -> Verdict:
        follow = self._result(rt, "robot_1", self._follow)
        peer = self._result(rt, "robot_3", self._peer)
        operator = self._result(rt, "robot_4", self._operator)
        criteria = [
            ("robot_2 follows robot_1 (Follow ACCEPTED)", self.follow_accepted_s is not None),
            ("robot_3's Goto TEMPORARILY_REJECTED (motion held)",
             peer is not None and (peer.result, peer.reason) == (ResultCode.TEMPORARILY_REJECTED, Reason.MOTION_HELD)),
            ("robot_4's (operator) Goto ACCEPTED", operator is not None and operator.result in (
                ResultCode.ACCEPTED, ResultCode.IN_PROGRESS, ResultCode.DONE)),
            ("robot_1's Follow ended CANCELLED (replaced)",
             follow is not None and (follow.result, follow.reason) == (ResultCode.CANCELLED, Reason.REPLACED)),
            no_collisions(rt),
        ]
        metrics = {
            "ranks": {f"robot_{a}": r.name for a, r in RANKS.items()},
            "follow_accepted_s": self.follow_accepted_s,
            "peer_answer": None if peer is None else [peer.result.name, peer.reason.name],
            "operator_answer": None if operator is None else [operator.result.name, operator.reason.name],
            "follow_end": None if follow is None else [follow.result.name, follow.reason.name],
            "peer_answered_s": self.peer_answered_s,
            "operator_answered_s": self.operator_answered_s,
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)
