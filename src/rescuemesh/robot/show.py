"""ShowScan and ShowCam (paper Table III: "send image of the specified position"): go where the
position is in sight, face it, and hand over encoded captures once or periodically.

Owns: the viewpoint search (line of sight on the map's grid), the move/aim/capture phases. Must
not know the simulator, the wire or the requester: the brain gives it a `capture` callable that
returns (DataKind, bytes) and sends what it hands over.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable

import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav import Costmap, GoalStatus, NavigateToPose, NavReason
from rescuemesh.protocol import DataKind, Reason, ResultCode
from rescuemesh.robot.behaviours import STOPPED, Behaviour

#: Rings (m) around the requested position where a viewpoint is looked for, and points per ring.
VIEW_RADII_M = (1.5, 2.5, 3.5)
VIEW_BEARINGS = 24
AIM_TOLERANCE_RAD = 0.08
AIM_GAIN, AIM_MAX_RAD_S = 2.0, 1.0


class Phase(enum.Enum):
    MOVE = "move"
    AIM = "aim"
    CAPTURE = "capture"


def line_of_sight(costmap: Costmap, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """No static obstacle of the map on the segment a-b (sampled at half a cell)."""
    grid = costmap.grid
    steps = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (grid.resolution / 2)) + 1)
    for t in np.linspace(0.0, 1.0, steps)[1:-1]:
        if grid.is_occupied(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])):
            return False
    return True


def sees(costmap: Costmap, viewpoint: Pose2D, target: tuple[float, float], range_m: float) -> bool:
    distance = math.hypot(target[0] - viewpoint.x, target[1] - viewpoint.y)
    return distance <= range_m and line_of_sight(costmap, (viewpoint.x, viewpoint.y), target)


def find_viewpoint(costmap: Costmap, start: Pose2D, target: tuple[float, float], range_m: float) -> Pose2D | None:
    """Where to stand to sense `target`: `start` if it already sees it, otherwise the free spot on
    the rings around the target that sees it and is nearest to `start`, facing the target; None if
    there is no such spot."""
    if sees(costmap, start, target, range_m):
        return Pose2D(start.x, start.y, math.atan2(target[1] - start.y, target[0] - start.x))
    best, best_d = None, math.inf
    for radius in VIEW_RADII_M:
        if radius > range_m:
            continue
        for k in range(VIEW_BEARINGS):
            bearing = 2 * math.pi * k / VIEW_BEARINGS
            x, y = target[0] + radius * math.cos(bearing), target[1] + radius * math.sin(bearing)
            if not costmap.is_free(x, y) or not line_of_sight(costmap, (x, y), target):
                continue
            d = math.hypot(x - start.x, y - start.y)
            if d < best_d:
                best, best_d = Pose2D(x, y, wrap_angle(bearing + math.pi)), d
    return best


class ShowBehaviour(Behaviour):
    """Move to a viewpoint, face the target, then capture `count` times `period_s` apart (count 0:
    until Stop or `timeout_s`). Each capture is appended to `outbox` as (DataKind, bytes)."""

    def __init__(self, nav: NavigateToPose, costmap: Costmap, name: str, target: tuple[float, float],
                 range_m: float, period_s: float, count: int,
                 capture: Callable[[], tuple[DataKind, bytes] | None],
                 now: float, start: Pose2D, *, timeout_s: float = 120.0, stationary: bool = False) -> None:
        """`stationary`: capture from wherever the robot is, without driving or turning (a ShowScan
        that runs beside a drive, when the position is already in sight)."""
        super().__init__(nav)
        self.name = name
        self.target, self.period_s, self.count, self.timeout_s = target, period_s, count, timeout_s
        self.capture = capture
        self.started_s = now
        self.captures = 0
        self.outbox: list[tuple[DataKind, bytes]] = []
        self._next_capture_s = 0.0
        self.viewpoint = start if stationary else find_viewpoint(costmap, start, target, range_m)
        self.moved = False
        if stationary:
            self.phase = Phase.CAPTURE
        elif self.viewpoint is None:
            self.phase = Phase.AIM
            self._finish(ResultCode.FAILED, Reason.NO_VIEWPOINT,
                         f"no reachable spot within {range_m:g} m sees ({target[0]:.2f}, {target[1]:.2f})")
        elif start.distance_to(self.viewpoint) < 0.05:
            self.phase = Phase.AIM
        else:
            self.phase = Phase.MOVE
            self.moved = True
            self._goal_id = self._send_nav_goal(self.viewpoint, now, check_yaw=False)

    def progress(self) -> int:
        if self.count == 0:
            return 255
        return min(99, int(100 * self.captures / self.count))

    def _restart(self, now: float) -> None:
        if self.phase is Phase.MOVE:
            self._goal_id = self._send_nav_goal(self.viewpoint, now, check_yaw=False)

    def step(self, now: float, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float]:
        if self.paused or self.finished:
            return STOPPED
        if self.count == 0 and now - self.started_s > self.timeout_s:
            return self._finish(ResultCode.DONE, Reason.TIMEOUT, f"{self.captures} captures in {self.timeout_s:g} s")
        if self.phase is Phase.MOVE:
            v_w = self.nav.step(now, pose, scan)
            while (result := self.nav.next_result()) is not None:
                if result.goal_id != self._goal_id:
                    continue
                if result.status is not GoalStatus.SUCCEEDED:
                    reason = Reason.NO_PATH if result.reason is NavReason.NO_PATH else Reason.STUCK
                    return self._finish(ResultCode.FAILED, reason, f"to the viewpoint: {result.reason}")
                self.phase = Phase.AIM
                return STOPPED
            return v_w
        error = wrap_angle(math.atan2(self.target[1] - pose.y, self.target[0] - pose.x) - pose.yaw)
        if self.phase is Phase.AIM:
            if abs(error) > AIM_TOLERANCE_RAD:
                return (0.0, max(-AIM_MAX_RAD_S, min(AIM_MAX_RAD_S, AIM_GAIN * error)))
            self.phase, self._next_capture_s = Phase.CAPTURE, now
        if now + 1e-9 >= self._next_capture_s:
            try:
                item = self.capture()
            except RuntimeError as error:  # rescuemesh.body.NoRendererError
                return self._finish(ResultCode.FAILED, Reason.NO_RENDERER, str(error))
            if item is None:  # the sensor has nothing yet (no sweep taken): try at the next tick
                return STOPPED
            self.outbox.append(item)
            self.captures += 1
            self._next_capture_s = now + self.period_s
            if self.count and self.captures >= self.count:
                return self._finish(ResultCode.DONE)
        return STOPPED
