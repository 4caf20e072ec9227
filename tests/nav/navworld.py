"""Synthetic worlds for the navigation tests: small grids, a fake lidar for round obstacles, a unicycle.

Imported by the nav tests as `navworld` (a plain module: `conftest` is ambiguous between test folders)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.maps.grid import OccupancyGrid

RES = 0.05


def room_with_door() -> OccupancyGrid:
    """6 x 4 m room, border walls, a wall at x = 3.0..3.1 m with a 1 m doorway for y in [1.5, 2.5] m."""
    occ = np.zeros((80, 120), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 60:62] = True
    occ[30:50, 60:62] = False
    return OccupancyGrid(occ, RES, 0.0, 0.0)


def corridor() -> OccupancyGrid:
    """8 m long, 2 m wide passage (free y in [0.1, 2.1] m), walls all round."""
    occ = np.zeros((44, 160), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    return OccupancyGrid(occ, RES, 0.0, 0.0)


def fake_scan(pose: Pose2D, discs: list[tuple[float, float, float]], stamp: float) -> LaserScan:
    """A 240-degree, 0.5-degree scan from `pose` that sees only round obstacles (x, y, radius) m."""
    inc = math.radians(0.5)
    n = int(round(math.radians(240.0) / inc)) + 1
    angle_min = -math.radians(120.0)
    a = pose.yaw + angle_min + inc * np.arange(n)
    d = np.stack([np.cos(a), np.sin(a)], axis=1)
    ranges = np.full(n, np.inf)
    for cx, cy, r in discs:
        o = np.array([pose.x - cx, pose.y - cy])
        b = d @ o
        disc = b * b - (o @ o - r * r)
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        hit = (disc >= 0.0) & (t > 0.0)
        ranges = np.where(hit, np.minimum(ranges, t), ranges)
    ranges = np.where(ranges <= 5.6, ranges, np.inf)
    return LaserScan(stamp, pose, angle_min, inc, 0.02, 5.6, ranges)


@dataclass
class Run:
    pose: Pose2D
    now: float  # the next step's time
    last_step: float  # the time of the last step taken
    commands: list[tuple[float, float]]


def drive(nav, pose: Pose2D, now: float, seconds: float, *, discs=(), until_done: bool = True, dt: float = 0.05) -> Run:
    """Step `nav` at 1/dt Hz on a perfect unicycle (lidar at 10 Hz) for up to `seconds` s of fake time."""
    commands = []
    scan = None
    last = now
    for i in range(int(round(seconds / dt))):
        if discs and i % 2 == 0:
            scan = fake_scan(pose, list(discs), now)
        v, w = nav.step(now, pose, scan)
        last = now
        commands.append((v, w))
        x = pose.x + v * dt * math.cos(pose.yaw)
        y = pose.y + v * dt * math.sin(pose.yaw)
        pose = Pose2D(x, y, wrap_angle(pose.yaw + w * dt))
        now = round(now + dt, 9)
        if until_done and nav.status.value != "active":
            break
    return Run(pose, now, last, commands)
