"""A body without a physics engine: a unicycle that integrates its commanded twist over a clock, with a
lidar ray-cast on an occupancy grid. For robot processes on a real network without hardware, and tests.

Owns: KinematicBody (pose, odometry, scan, set_velocity). Must not know: MuJoCo, Zenoh, the brain.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rescuemesh.body import Body, LaserScan
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.maps.grid import OccupancyGrid

#: TurtleBot 2 (Kobuki) limits and footprint, as the simulated one (sim/mjcf.py).
MAX_LINEAR_SPEED = 0.7  # m/s
MAX_ANGULAR_SPEED = math.pi  # rad/s
RADIUS = 0.177  # m
#: The lidar, after the Hokuyo URG-04LX as the simulated one (sim/lidar.py), with fewer beams:
#: the ray-cast is numpy over a grid, and the navigator needs obstacles, not fine angles.
SCAN_FOV_RAD = math.radians(240.0)
SCAN_BEAMS = 241
SCAN_RATE_HZ = 10.0
SCAN_RANGE_MIN = 0.02  # m
SCAN_RANGE_MAX = 5.6  # m
#: Longest step of one integration, in s: a long gap (a stalled loop) is split into arcs this long.
MAX_INTEGRATION_STEP_S = 0.05


def empty_grid(center_x: float = 0.0, center_y: float = 0.0, size_m: float = 30.0,
               resolution: float = 0.1) -> OccupancyGrid:
    """A free square `size_m` m a side centred on (`center_x`, `center_y`): the map of a robot that
    has none (everything outside it is an obstacle to the planner)."""
    if not (size_m > 0 and resolution > 0 and size_m / resolution <= 10_000):
        raise ValueError(f"an empty grid needs size > 0 m and at most 10,000 cells a side, got {size_m} m "
                         f"at {resolution} m")
    cells = int(math.ceil(size_m / resolution))
    return OccupancyGrid(np.zeros((cells, cells), dtype=bool), resolution,
                         center_x - cells * resolution / 2, center_y - cells * resolution / 2)


class KinematicBody(Body):
    """A ground robot whose pose follows its commanded twist exactly (a unicycle, no slip, no inertia).

    `clock()` gives the time in s (the loop's clock: real time in a robot process, a fake one in
    tests); every call integrates the pose up to it. `grid`: what the lidar sees (None: no lidar,
    scan() is None and the navigator plans on its map only). Odometry is the true pose: there is
    no drift to model without wheels.
    """

    def __init__(self, name: str, start: Pose2D, clock: Callable[[], float], *, grid: OccupancyGrid | None = None,
                 max_linear_speed: float = MAX_LINEAR_SPEED, max_angular_speed: float = MAX_ANGULAR_SPEED,
                 radius: float = RADIUS, scan_beams: int = SCAN_BEAMS) -> None:
        self.name = name
        self.max_linear_speed = float(max_linear_speed)
        self.max_angular_speed = float(max_angular_speed)
        self.radius = float(radius)
        self._clock = clock
        self._t = float(clock())
        self._x, self._y, self._yaw = float(start.x), float(start.y), wrap_angle(float(start.yaw))
        self._v = self._w = 0.0
        self.distance_m = 0.0  # path length driven so far
        self._grid = grid
        self._angles = np.linspace(-SCAN_FOV_RAD / 2, SCAN_FOV_RAD / 2, scan_beams) if scan_beams > 1 else np.zeros(1)
        self._steps = np.arange(0.0, SCAN_RANGE_MAX, (grid.resolution / 2) if grid is not None else 1.0)
        self._scan: LaserScan | None = None

    # --- Body ---------------------------------------------------------------------------------------

    def pose(self) -> Pose2D:
        self._advance()
        return Pose2D(self._x, self._y, self._yaw)

    def odometry(self) -> tuple[Pose2D, float, float]:
        self._advance()
        return Pose2D(self._x, self._y, self._yaw), self._v, self._w

    def scan(self) -> LaserScan | None:
        """The latest sweep (a new one every 1 / SCAN_RATE_HZ s), or None without a grid."""
        if self._grid is None:
            return None
        self._advance()
        sweep = math.floor(self._t * SCAN_RATE_HZ)
        stamp = sweep / SCAN_RATE_HZ
        if self._scan is None or self._scan.stamp != stamp:
            self._scan = self._sweep(stamp)
        return self._scan

    def set_velocity(self, linear: float, angular: float) -> None:
        self._advance()
        if not (math.isfinite(linear) and math.isfinite(angular)):
            linear = angular = 0.0  # a NaN twist stops the robot rather than teleporting it
        self._v = min(max(float(linear), -self.max_linear_speed), self.max_linear_speed)
        self._w = min(max(float(angular), -self.max_angular_speed), self.max_angular_speed)

    # --- internals ----------------------------------------------------------------------------------

    def _advance(self) -> None:
        now = float(self._clock())
        dt_total = now - self._t
        if dt_total <= 0.0:
            return  # a clock that did not move (or went back) changes nothing
        self._t = now
        v, w = self._v, self._w
        if v == 0.0 and w == 0.0:
            return
        steps = max(1, math.ceil(dt_total / MAX_INTEGRATION_STEP_S))
        dt = dt_total / steps
        for _ in range(steps):
            if abs(w) < 1e-9:  # straight
                self._x += v * dt * math.cos(self._yaw)
                self._y += v * dt * math.sin(self._yaw)
            else:  # exact arc of radius v / w
                yaw2 = self._yaw + w * dt
                self._x += v / w * (math.sin(yaw2) - math.sin(self._yaw))
                self._y -= v / w * (math.cos(yaw2) - math.cos(self._yaw))
                self._yaw = yaw2
            self._yaw = wrap_angle(self._yaw)
        self.distance_m += abs(v) * dt_total

    def _sweep(self, stamp: float) -> LaserScan:
        """Ray-cast every beam on the grid: the first occupied (or off-grid) sample along it, in
        steps of half a cell (a wall one cell thick is never skipped)."""
        grid = self._grid
        angles = self._yaw + self._angles
        xs = self._x + np.outer(np.cos(angles), self._steps)  # (beams, samples)
        ys = self._y + np.outer(np.sin(angles), self._steps)
        rows = np.floor((ys - grid.origin_y) / grid.resolution).astype(np.int64)
        cols = np.floor((xs - grid.origin_x) / grid.resolution).astype(np.int64)
        n_rows, n_cols = grid.occupied.shape
        inside = (rows >= 0) & (rows < n_rows) & (cols >= 0) & (cols < n_cols)
        hit = ~inside
        hit[inside] = grid.occupied[rows[inside], cols[inside]]
        first = np.argmax(hit, axis=1)
        ranges = np.where(hit.any(axis=1), self._steps[first], np.inf)
        ranges = np.where(ranges < SCAN_RANGE_MIN, SCAN_RANGE_MIN, ranges)
        increment = float(self._angles[1] - self._angles[0]) if len(self._angles) > 1 else 0.0
        return LaserScan(stamp, Pose2D(self._x, self._y, self._yaw), float(self._angles[0]), increment,
                         SCAN_RANGE_MIN, SCAN_RANGE_MAX, ranges.astype(float))
