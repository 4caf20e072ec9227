"""Scenario `follow`: robot_1 drives from the hall through a doorway into a room; robot_2 follows.

Owns: the Follow mission script, its success criteria and metrics (paper section IV-A, Fig. 3).
Must not know: how the world is simulated or how results are written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import ResultCode
from rescuemesh.scenarios.base import (CommandRequest, Scenario, ScenarioError, Verdict, following_error,
                                       last_result, mean_distance, no_collisions, settled, why_not)

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: On a map with no named regions, follow succeeds when the follower ends this close to the leader (m).
FOLLOWER_END_DISTANCE_M = 2.0


class FollowScenario(Scenario):
    name = "follow"
    summary = "robot_1 drives through a doorway into another room; robot_2 follows it; robot_3 stays put"
    time_limit_s = 120.0
    leader, follower = "robot_1", "robot_2"
    runs_as_processes = True
    takes_goal = True

    def validate(self) -> None:
        self.require_free("goal", self.goal())

    def mission_point(self) -> Pose2D:
        return self.goal()

    def goal(self) -> Pose2D:
        if self.options.goal is not None:
            return self.options.goal
        if "follow_leader" in self.map.goals:
            return self.map.goals["follow_leader"]
        raise ScenarioError(f"map {self.map.name!r} has no default goal for the leader: give --goal X,Y")

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._request: CommandRequest | None = None
        self.accepted_s: float | None = None
        self.arrived_s: float | None = None
        self.settled_s: float | None = None
        self._leader_result: ResultCode | None = None

    def tick(self, rt: SimRuntime) -> None:
        now = rt.time
        leader = rt.brain(self.leader)
        if self._request is None:
            self._request = CommandRequest(leader, self.follower, leader.command_follow)
        if self.accepted_s is None:
            if self._request.poll(now) == ResultCode.ACCEPTED:
                self.accepted_s = now
                leader.navigate_to(self.goal(), now)
            return
        if self.arrived_s is None and leader.running is None:
            self.arrived_s = now
            self._leader_result = last_result(leader, "navigate")
        if self.arrived_s is not None and self.settled_s is None and settled(rt, self.follower, self.arrived_s):
            self.settled_s = now

    def finished(self, rt: SimRuntime) -> bool:
        return self.settled_s is not None or (self._request is not None and self._request.given_up)

    def evaluate(self, rt: SimRuntime) -> Verdict:
        leader_end = rt.trajectories[self.leader][-1].pose
        follower_end = rt.trajectories[self.follower][-1].pose
        goal = self.goal()
        goal_region = self.map.region_of(goal.x, goal.y)
        criteria = [("Follow confirmed ACCEPTED", self.accepted_s is not None),
                    (f"leader reached its goal{why_not(rt.brain(self.leader), 'navigate')}",
                     self._leader_result == ResultCode.DONE)]
        passed_doorway = None
        if goal_region is not None and self.map.regions:
            start = rt.trajectories[self.follower][0].pose
            start_region = self.map.region_of(start.x, start.y)
            follower_region = self.map.region_of(follower_end.x, follower_end.y)
            passed_doorway = start_region != goal_region and follower_region == goal_region
            criteria += [(f"leader ends in {goal_region}", self.map.region_of(leader_end.x, leader_end.y) == goal_region),
                         (f"follower ends in {goal_region}", follower_region == goal_region)]
        else:
            gap = leader_end.distance_to(follower_end)
            criteria.append((f"follower ends within {FOLLOWER_END_DISTANCE_M} m of the leader ({gap:.2f} m)",
                             gap <= FOLLOWER_END_DISTANCE_M))
        criteria.append(no_collisions(rt))
        following = error = None
        if self.accepted_s is not None:  # the window: from the Follow's ACCEPTED to the leader's arrival
            leader_path, follower_path = rt.trajectories[self.leader], rt.trajectories[self.follower]
            window_end = self.arrived_s or rt.time
            following = _round(mean_distance(leader_path, follower_path, self.accepted_s, window_end))
            error = following_error(leader_path, follower_path, self.accepted_s, window_end,
                                    rt.config.brain.follow_distance_m)
        metrics = {
            "follower_passed_doorway": passed_doorway,
            "mean_following_distance_m": following,
            "following_error_m": error,
            "final_gap_m": round(leader_end.distance_to(follower_end), 3),
            "follow_accepted_s": self.accepted_s,
            "leader_arrived_s": self.arrived_s,
            "goal": [goal.x, goal.y],
            "goal_region": goal_region,
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def _round(value: float, digits: int = 3):
    return None if value != value else round(value, digits)
