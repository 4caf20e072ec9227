"""The interface between a robot's brain and its body, and the sensor messages that cross it.

Owns: Body (what the brain may ask of a body), LaserScan (sensor_msgs/LaserScan in spirit).
Must not know: what implements a body (MuJoCo, a remote process, a ROS robot).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from rescuemesh.geometry import Pose2D


@dataclass(frozen=True)
class LaserScan:
    """One planar laser sweep, as sensor_msgs/LaserScan.

    Beam i points at `angle_min + i * angle_increment` rad in the sensor frame (x forward,
    anticlockwise positive). `ranges` in m; a beam with no return within `range_max` is `inf`.
    `origin` is the sensor pose in the map frame when the sweep was taken, at `stamp` s.
    """

    stamp: float
    origin: Pose2D
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray

    def angles(self) -> np.ndarray:
        """Beam angles in rad in the sensor frame."""
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def points_in_map(self) -> np.ndarray:
        """(N, 2) map-frame points of the finite returns within [range_min, range_max]."""
        r = self.ranges
        ok = np.isfinite(r) & (r >= self.range_min) & (r <= self.range_max)
        a = self.angles()[ok] + self.origin.yaw
        return np.stack([self.origin.x + r[ok] * np.cos(a), self.origin.y + r[ok] * np.sin(a)], axis=1)


class Body(abc.ABC):
    """What a robot brain may read from and command to its body.

    Implemented by `rescuemesh.sim` for MuJoCo TurtleBots; later by a Zenoh proxy and a ROS bridge.
    """

    name: str
    max_linear_speed: float  # in m/s
    max_angular_speed: float  # in rad/s
    radius: float  # footprint radius in m

    @abc.abstractmethod
    def pose(self) -> Pose2D:
        """Localised pose in the `map` frame (ground truth in simulation, as AMCL would give)."""

    @abc.abstractmethod
    def odometry(self) -> tuple[Pose2D, float, float]:
        """Odometry: (dead-reckoned pose, linear speed in m/s, angular speed in rad/s)."""

    @abc.abstractmethod
    def scan(self) -> LaserScan | None:
        """The latest complete laser sweep, or None before the first one."""

    @abc.abstractmethod
    def set_velocity(self, linear: float, angular: float) -> None:
        """Command a body twist: `linear` in m/s along x, `angular` in rad/s about z. Clamped to the limits."""
