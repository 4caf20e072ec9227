"""Scenario `move-around`: robot_1 sends MoveAround(radius); robot_2 circles it anticlockwise.

Owns: the MoveAround mission script, its success criteria and circle metrics (paper IV-C, Fig. 5).
Must not know: how the world is simulated or how results are written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math

import numpy as np

from rescuemesh.protocol import ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.robot.behaviours import MoveAroundBehaviour
from rescuemesh.scenarios.base import CommandRequest, Scenario, ScenarioError, Verdict, no_collisions

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

MAX_RMS_ERROR_M = 0.15
MIN_ANGLE_DEG = 330.0
#: The circle must clear both robots' footprints (2 x 0.18 m) with room to steer.
MIN_RADIUS_M = 0.6
#: Metrics start once robot_2 is this close to the circle (m): the approach leg is not circling.
ON_CIRCLE_M = 0.1


class MoveAroundScenario(Scenario):
    name = "move-around"
    runs_as_processes = True
    summary = "robot_1 sends MoveAround(radius); robot_2 circles robot_1 anticlockwise"
    time_limit_s = 150.0
    center, mover = "robot_1", "robot_2"

    def validate(self) -> None:
        r = self.options.radius_m
        b = self.map.bounds
        extent = max(b.x_max - b.x_min, b.y_max - b.y_min)
        if not math.isfinite(r) or r <= 0:
            raise ScenarioError(f"radius must be a positive number of metres, got {r}")
        if 2 * r > extent:
            raise ScenarioError(f"radius {r} m is larger than the map ({extent:.1f} m across)")
        if r < MIN_RADIUS_M:
            raise ScenarioError(f"radius {r} m is too small: robot_2 would hit robot_1 (minimum {MIN_RADIUS_M} m)")

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._request: CommandRequest | None = None
        self.result: ResultCode | None = None
        self.accepted_s: float | None = None
        self.center_pose = None
        self.waypoints: list[dict] = []

    def tick(self, rt: SimRuntime) -> None:
        brain = rt.brain(self.center)
        if self._request is None:
            self.center_pose = brain.body.pose()
            self._request = CommandRequest(brain, self.mover,
                                           lambda peer, now: brain.command_move_around(peer, self.options.radius_m, now))
        if self.result is None:
            self.result = self._request.poll(rt.time)
            if self.result is not None:
                self.accepted_s = rt.time
        running = rt.brain(self.mover).running
        if not self.waypoints and running is not None:
            behaviour = running.behaviour  # by name, not isinstance: with --processes it is a stand-in
            if behaviour.name == "move-around":
                self.waypoints = waypoint_table(behaviour)

    def _ended(self, rt: SimRuntime):
        """The end of the circle the confirmed command started (not of a copy given up and stopped)."""
        if self.accepted_s is None:
            return None
        brain = rt.brain(self.mover)
        starts = [f.started_s for f in brain.finished if f.name == "move-around"]
        if brain.running is not None and brain.running.behaviour.name == "move-around":
            starts.append(brain.running.started_s)
        confirmed = max((t for t in starts if t <= self.accepted_s), default=None)
        return next((f for f in brain.finished if f.name == "move-around" and f.started_s == confirmed), None)

    def finished(self, rt: SimRuntime) -> bool:
        if self.result is not None and self.result != ResultCode.ACCEPTED:
            return True
        return self._ended(rt) is not None or (self._request is not None and self._request.given_up)

    def evaluate(self, rt: SimRuntime) -> Verdict:
        r = self.options.radius_m
        c = self.center_pose
        ended = self._ended(rt)
        end_s = ended.ended_s if ended else rt.time
        samples = [s for s in rt.trajectories[self.mover] if s.time_s <= end_s]
        xy = np.array([[s.pose.x, s.pose.y] for s in samples])
        dist = np.hypot(xy[:, 0] - c.x, xy[:, 1] - c.y)
        on = np.flatnonzero(np.abs(dist - r) <= ON_CIRCLE_M)
        rms = angle = None
        if on.size:
            window = slice(on[0], None)
            rms = float(np.sqrt(np.mean((dist[window] - r) ** 2)))
            theta = np.unwrap(np.arctan2(xy[window, 1] - c.y, xy[window, 0] - c.x))
            angle = float(np.degrees(theta[-1] - theta[0]))
        skipped = [e.indices for e in rt.brain(self.mover).log if isinstance(e, ev.WaypointsSkipped)]
        criteria = [
            ("MoveAround confirmed ACCEPTED", self.result == ResultCode.ACCEPTED),
            ("robot_2 finished the circle", ended is not None and ended.result == ResultCode.DONE),
            (f"RMS radius error <= {MAX_RMS_ERROR_M} m", rms is not None and rms <= MAX_RMS_ERROR_M),
            (f"at least {MIN_ANGLE_DEG:.0f} degrees covered anticlockwise", angle is not None and angle >= MIN_ANGLE_DEG),
            no_collisions(rt),
        ]
        metrics = {
            "radius_m": r,
            "center": [round(c.x, 3), round(c.y, 3)],
            "radius_rms_error_m": None if rms is None else round(rms, 4),
            "angle_covered_deg": None if angle is None else round(angle, 1),
            "waypoints_skipped": [str(i) for i in skipped[0]] if skipped else [],
            "circle_time_s": None if not on.size else round(end_s - samples[on[0]].time_s, 2),
            "waypoints": self.waypoints,
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def waypoint_table(behaviour: MoveAroundBehaviour) -> list[dict]:
    """The circle's waypoints in visiting order, each with its tangent heading as a quaternion."""
    skipped = {w.index for w in behaviour.skipped}
    rows = [{"index": w.index, "x": round(w.pose.x, 3), "y": round(w.pose.y, 3), "yaw": round(w.pose.yaw, 4),
             "quaternion_xyzw": [round(q, 4) for q in w.quaternion], "skipped": False}
            for w in behaviour.waypoints]
    rows += [{"index": i, "skipped": True} for i in sorted(skipped)]
    return rows
