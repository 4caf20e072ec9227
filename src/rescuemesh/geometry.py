"""Planar poses and angles shared by every layer (REP-103: x forward, y left, yaw about z, frame `map`).

Owns: Pose2D, angle wrapping, yaw <-> quaternion. Knows nothing of robots, maps or the protocol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


def wrap_angle(angle: float) -> float:
    """Wrap an angle in rad to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def yaw_to_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation by `yaw` rad about z (geometry_msgs/Quaternion order)."""
    half = 0.5 * yaw
    return (0.0, 0.0, math.sin(half), math.cos(half))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw in rad of a quaternion (x, y, z, w); roll and pitch are ignored."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True, slots=True)
class Pose2D:
    """A pose in the `map` frame: position in m, yaw in rad (anticlockwise from +x)."""

    x: float
    y: float
    yaw: float = 0.0

    def distance_to(self, other: "Pose2D") -> float:
        """Euclidean distance in m between the two positions."""
        return math.hypot(other.x - self.x, other.y - self.y)

    def bearing_to(self, other: "Pose2D") -> float:
        """Angle in rad, in the map frame, of the direction from this position to `other`."""
        return math.atan2(other.y - self.y, other.x - self.x)
