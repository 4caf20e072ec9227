"""What a ROS 1 and a ROS 2 body share: the latest odometry, localised pose and scan kept under a
lock by the middleware's threads, read by the runtime's thread, and the ROS clock as the brain's.

Owns: that state and the Body methods that only read it. Must not know: rospy or rclpy (each body
gives its clock and says how its odometry topic is named and what to check when none arrives).
"""

from __future__ import annotations

import abc
import math
import threading
import time

from rescuemesh.body import Body, LaserScan
from rescuemesh.geometry import Pose2D


class NoOdometryError(RuntimeError):
    """No Odometry arrived in time: the robot, the topic name or the middleware's set-up is wrong."""


class RosBodyState(Body, abc.ABC):
    """The latest Odometry (pose, v, omega), localised pose and scan, with the time they came."""

    #: The odometry message's type as this ROS names it, for messages.
    odometry_type: str = "nav_msgs/Odometry"

    def _init_state(self, time_origin: float) -> None:
        #: ROS time in s that is `now()` == 0 (the brain's clock starts near 0, as in simulation).
        self.time_origin = time_origin
        self._lock = threading.Lock()
        self._odom: tuple[Pose2D, float, float] | None = None
        self._odom_received_s: float | None = None  # ROS time of the latest Odometry's arrival
        self._localised: Pose2D | None = None
        self._scan: LaserScan | None = None
        self._odometry_arrived = threading.Event()

    @abc.abstractmethod
    def _ros_seconds(self) -> float:
        """The ROS clock, in s."""

    @abc.abstractmethod
    def _ros_running(self) -> bool:
        """False once the node is shut down."""

    @abc.abstractmethod
    def _odometry_topic(self) -> str:
        """The odometry topic's name, as resolved."""

    @abc.abstractmethod
    def _no_odometry_hint(self) -> str:
        """What to check when no Odometry arrives."""

    def wait_for_odometry(self, timeout_s: float) -> None:
        """Block until an Odometry has arrived, or raise NoOdometryError after `timeout_s` s (wall time)."""
        deadline = time.monotonic() + timeout_s
        while not self._odometry_arrived.wait(0.1):
            if not self._ros_running() or time.monotonic() >= deadline:
                raise NoOdometryError(
                    f"{self.name}: no {self.odometry_type} on {self._odometry_topic()} within {timeout_s:g} s: "
                    f"{self._no_odometry_hint()}")

    def now(self) -> float:
        """ROS time in s since `time_origin`: the clock to step this robot's brain with."""
        return self._ros_seconds() - self.time_origin

    def odometry_age(self) -> float:
        """Seconds since the latest Odometry arrived (ROS time): a runtime may halt on a stale one."""
        with self._lock:
            received = self._odom_received_s
        return math.inf if received is None else self._ros_seconds() - received

    def _latest_odometry(self) -> tuple[Pose2D, float, float]:
        with self._lock:
            odom = self._odom
        if odom is None:
            raise NoOdometryError(f"{self.name}: no {self.odometry_type} on {self._odometry_topic()} yet")
        return odom

    def pose(self) -> Pose2D:
        """The localised pose (the pose topic's latest) or, without one, the odometry's pose."""
        with self._lock:
            localised = self._localised
        return localised if localised is not None else self._latest_odometry()[0]

    def odometry(self) -> tuple[Pose2D, float, float]:
        return self._latest_odometry()

    def scan(self) -> LaserScan | None:
        with self._lock:
            return self._scan

    def _clamped(self, linear: float, angular: float) -> tuple[float, float]:
        """The command within the body's limits; ValueError if it is not finite."""
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"{self.name}: velocity command must be finite, got ({linear}, {angular})")
        return (min(max(float(linear), -self.max_linear_speed), self.max_linear_speed),
                min(max(float(angular), -self.max_angular_speed), self.max_angular_speed))
