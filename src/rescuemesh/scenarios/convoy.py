"""Scenario `convoy`: a team of N robots in a chain. robot_2 follows robot_1, robot_3 follows
robot_2, and so on; robot_1 leads the chain through the passage and a doorway into a far room.

Owns: the convoy mission (forming the chain link by link, the leader's route), its success
criteria and metrics. Must not know: how the world or the radio is simulated, how results are
written.

On the office the team starts in room_east (and room_northeast when it is large) behind robot_1,
which waits at room_east's doorway; the far room is the hall, the only room large enough for a
chain of 30 at the following distance (30 m of chain: room_east is 5.7 m x 5.9 m). The leader
crosses the passage, enters the hall through its doorway and drives a hook-shaped route inside it
(HALL_ROUTE, about 34 m) so that the whole chain is pulled in behind it. On any other map the
leader drives to --goal (or the map's `convoy_leader` or `follow_leader` goal), the others are
placed behind robot_1 automatically unless each has a --start, and success asks for an unbroken
chain instead of a room.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import replace
from functools import cached_property

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import robot_address
from rescuemesh.robot.records import power_on_s
from rescuemesh.scenarios.base import (CommandRequest, Scenario, ScenarioError, Verdict, following_error,
                                       last_result, mean_distance,
                                       no_collisions, settled, why_not)
from rescuemesh.scenarios.team import MAX_TEAM, PlacementError, place_behind, team_names

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: Team size without --robots.
DEFAULT_TEAM = 6
#: Office: robot_1 waits inside room_east at its doorway to the passage, facing west.
OFFICE_LEADER_START = Pose2D(14.4, 4.6, math.pi)
#: Office: where the rest of the team may start.
OFFICE_TEAM_REGIONS = ("room_east", "room_northeast")
#: Office: the leader's route after the passage: into the hall, north along its east side, west
#: along its north wall, south along its west wall, east along its south wall, then a smaller hook
#: inside (clear of the pillar at (2.2, 2.2)). Legs are >= 1.6 m apart, so a follower never sees a
#: shorter way to its leader across two legs.
HALL_ROUTE = ((7.8, 5.0), (7.8, 8.2), (1.0, 8.2), (1.0, 1.0), (6.5, 1.0), (6.5, 2.9), (3.2, 2.9), (3.2, 6.6),
              (6.0, 6.6))
#: Commands (each the protocol's three sends) a link of the chain may take to form: the air of a
#: team of 30 forming at 20 % extra loss gave a Follow up three times in a row on one seed of three.
LINK_ATTEMPTS = 8
#: Centre-to-centre following distance in m of a convoy (the Follow scenario keeps the paper's 1 m):
#: two TurtleBot 2 footprints (0.354 m) and a quarter metre between bumpers, so a chain of 30 is
#: about 17 m long at rest and fits in the hall.
CONVOY_FOLLOW_DISTANCE_M = 0.6
#: The team is switched on within this many s (robot/records.py, power_on_s), as a real team is (by
#: hand, or booting at its own pace), not all on one tick: 30 robots' first Heartbeats and their
#: relays on one tick jammed the air, and robot_1's first Follow was given up at 0.5 s.
POWER_ON_SPREAD_S = 2.0
#: A final gap (centre to centre, m) counts as close to the following distance within these bounds:
#: at least two footprints and a little room apart, at most the following distance plus 0.6 m.
MIN_GAP_M = 0.4
MAX_GAP_M = CONVOY_FOLLOW_DISTANCE_M + 0.6


class ConvoyScenario(Scenario):
    name = "convoy"
    runs_as_processes = True
    summary = ("a chain of N robots (--robots, default 6): each follows the one ahead; robot_1 leads through the "
               "passage and a doorway into the hall")
    time_limit_s = 400.0
    takes_team_size = True
    takes_goal = True

    def __init__(self, options, map_model) -> None:
        count = DEFAULT_TEAM if options.robots is None else options.robots
        if not 2 <= count <= MAX_TEAM:
            raise ScenarioError(f"--robots must be from 2 to {MAX_TEAM}, got {count}")
        self.robots = team_names(count)
        super().__init__(options, map_model)
        self._links: list[CommandRequest] = []  # link k: robot_{k+1} asks robot_{k+2} to follow it
        self.formed_s: float | None = None
        self._leg = -1
        self.arrived_s: float | None = None
        self.settled_s: float | None = None
        self._leader_result: ResultCode | None = None

    # --- set-up ----------------------------------------------------------------------------------

    @cached_property
    def route(self) -> list[Pose2D]:
        """The leader's goals in order: --goal alone, else HALL_ROUTE on the office, else the map's goal."""
        if self.options.goal is not None:
            return [self.options.goal]
        if self.on_office:
            return [Pose2D(x, y, 0.0) for x, y in HALL_ROUTE]
        for key in ("convoy_leader", "follow_leader"):
            if key in self.map.goals:
                return [self.map.goals[key]]
        raise ScenarioError(f"map {self.map.name!r} has no default goal for the convoy's leader: give --goal X,Y")

    def validate(self) -> None:
        route = self.route
        for index, point in enumerate(route):
            self.require_free("goal" if len(route) == 1 else f"route point {index + 1}", point)

    def default_starts(self) -> dict[str, Pose2D]:
        given = self.options.starts
        if all(name in given for name in self.robots):
            return {}
        leader = given.get("robot_1")
        if leader is None:
            leader = OFFICE_LEADER_START if self.on_office else self.map.starts.get("robot_1")
        if leader is None:
            raise ScenarioError(f"map {self.map.name!r} has no start for robot_1: give --start robot_1=X,Y,YAW")
        allowed = [self.map.regions[r] for r in OFFICE_TEAM_REGIONS] if self.on_office and "robot_1" not in given else []
        self.require_free("start of robot_1", leader)
        goal = self.route[0]
        try:
            poses = place_behind(self.map.grid, leader, (goal.x, goal.y), len(self.robots), allowed=allowed)
        except PlacementError as error:
            raise ScenarioError(f"convoy of {len(self.robots)} on map {self.map.name!r}: {error}") from None
        return dict(zip(self.robots, poses))

    def sim_config(self):
        config = super().sim_config()
        return replace(config, brain=replace(config.brain, follow_distance_m=CONVOY_FOLLOW_DISTANCE_M,
                                             power_on_spread_s=POWER_ON_SPREAD_S))

    # --- the mission -----------------------------------------------------------------------------

    def tick(self, rt: SimRuntime) -> None:
        now = rt.time
        if self.formed_s is None:
            if now >= self._team_up_s(rt):
                self._form(rt, now)
            return
        leader = rt.brain(self.robots[0])
        route = self.route
        if self._leg < len(route) and leader.running is None:  # starting, or a leg has ended
            result = last_result(leader, "navigate")
            if self._leg + 1 < len(route) and (self._leg < 0 or result == ResultCode.DONE):
                self._leg += 1
                leader.navigate_to(route[self._leg], now)
            else:  # the last leg ended, or a leg failed: the route is over
                self._leader_result, self.arrived_s, self._leg = result, now, len(route)
        if self.arrived_s is not None and self.settled_s is None:
            if all(settled(rt, name, self.arrived_s) for name in self.robots):
                self.settled_s = now

    def _team_up_s(self, rt: SimRuntime) -> float:
        """When the mission starts: once the whole team is switched on and each robot has had a
        heartbeat period to hear the others' Heartbeats (their epochs: before, it cannot open their
        frames), as an operator starts a team's mission once it is up."""
        config = rt.config.brain
        last = max(power_on_s(robot_address(name), config.power_on_spread_s) for name in self.robots)
        return last + rt.config.mesh.heartbeat_period_s if last > 0.0 else 0.0

    def _form(self, rt: SimRuntime, now: float) -> None:
        """One link at a time from the front: robot_k asks robot_k+1 once robot_k itself follows."""
        if not self._links or self._links[-1].poll(now) == ResultCode.ACCEPTED:
            k = len(self._links)
            if k == len(self.robots) - 1:
                self.formed_s = now
                return
            leader = rt.brain(self.robots[k])
            self._links.append(CommandRequest(leader, self.robots[k + 1], leader.command_follow,
                                              attempts=LINK_ATTEMPTS))
            self._links[-1].poll(now)

    def finished(self, rt: SimRuntime) -> bool:
        return self.settled_s is not None or any(link.given_up for link in self._links)

    # --- the verdict -----------------------------------------------------------------------------

    def evaluate(self, rt: SimRuntime) -> Verdict:
        names = self.robots
        ends = [rt.trajectories[name][-1].pose for name in names]
        gaps = [ends[k].distance_to(ends[k + 1]) for k in range(len(ends) - 1)]
        answers = [link.confirmed() for link in self._links]
        accepted = sum(1 for answer in answers if answer is not None and answer.result == ResultCode.ACCEPTED)
        route = self.route
        criteria = [
            (f"Follow confirmed ACCEPTED on every link ({accepted}/{len(names) - 1})", accepted == len(names) - 1),
            (f"leader drove its route ({len(route)} point{'s' if len(route) > 1 else ''})"
             f"{why_not(rt.brain(names[0]), 'navigate')}", self._leader_result == ResultCode.DONE),
        ]
        room = self.map.region_of(route[-1].x, route[-1].y) if self.map.regions else None  # the hall, on the office
        if room is not None:
            inside = [self.map.region_of(p.x, p.y) == room for p in ends]
            outside = [name for name, ok in zip(names, inside) if not ok]
            criteria.append((f"every robot ends in {room} ({sum(inside)}/{len(names)}"
                             f"{'; not: ' + _short_list(outside) if outside else ''})", not outside))
        far = [f"{names[k + 1]} {g:.2f} m" for k, g in enumerate(gaps) if not MIN_GAP_M <= g <= MAX_GAP_M]
        criteria.append((f"every gap ends between {MIN_GAP_M} and {MAX_GAP_M} m (following distance "
                         f"{rt.config.brain.follow_distance_m} m; {min(gaps):.2f}-{max(gaps):.2f} m"
                         f"{'; off: ' + _short_list(far) if far else ''})", not far))
        criteria.append(no_collisions(rt))
        moving_gaps, errors = [], []
        if self.formed_s is not None:  # the window: from the chain's forming to the leader's arrival
            t1 = self.arrived_s or rt.time
            paths = [rt.trajectories[name] for name in names]
            moving_gaps = [mean_distance(paths[k], paths[k + 1], self.formed_s, t1) for k in range(len(names) - 1)]
            errors = [following_error(paths[k], paths[k + 1], self.formed_s, t1, rt.config.brain.follow_distance_m)
                      for k in range(len(names) - 1)]
            errors = [e for e in errors if e is not None]
        metrics = {
            "robots": len(names),
            "chain_formed_s": self.formed_s,
            "leader_arrived_s": self.arrived_s,
            "settled_s": self.settled_s,
            "final_gap_min_m": round(min(gaps), 3),
            "final_gap_mean_m": round(sum(gaps) / len(gaps), 3),
            "final_gap_max_m": round(max(gaps), 3),
            "mean_following_distance_m": _round_mean(moving_gaps),
            "following_error_m": _pooled_error(errors),
            "goal_room": room,
            "final_gaps_m": [round(g, 3) for g in gaps],
            "goal": [route[-1].x, route[-1].y],
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def _short_list(items: list[str], limit: int = 4) -> str:
    return ", ".join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")


def _pooled_error(errors: list[dict]) -> dict | None:
    """following_error over every link at once (each link's samples weigh as many as they are)."""
    n = sum(e["samples"] for e in errors)
    if not n:
        return None
    return {"set_distance_m": errors[0]["set_distance_m"],
            "mean_m": round(sum(e["mean_m"] * e["samples"] for e in errors) / n, 3),
            "rms_m": round(math.sqrt(sum(e["rms_m"] ** 2 * e["samples"] for e in errors) / n), 3),
            "max_m": max(e["max_m"] for e in errors), "samples": n, "links": len(errors)}


def _round_mean(values: list[float]):
    values = [v for v in values if v == v]
    return round(sum(values) / len(values), 3) if values else None
