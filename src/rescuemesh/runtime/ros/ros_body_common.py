"""What a ROS 1 and a ROS 2 body share: the latest odometry, localised pose and scan kept under a
lock by the middleware's threads, read by the runtime's thread, and the ROS clock as the brain's.

Owns: that state, the subscriptions' callbacks that fill it and the Body methods that only read it;
the conversions of the messages both ROS versions define alike (nav_msgs Odometry, geometry_msgs
Pose, sensor_msgs LaserScan: same fields, read by name); the TurtleBot 2 limits a body defaults to;
importing a middleware or saying what to install. Must not know: rospy or rclpy (each body gives its
clock, its logger, its message stamps and topic names, and what to check when no odometry arrives).
"""

from __future__ import annotations

import abc
import importlib
import math
import threading
import time

import numpy as np

from rescuemesh.body import Body, LaserScan
from rescuemesh.geometry import Pose2D, quaternion_to_yaw

#: TurtleBot 2 (Kobuki) limits and footprint, as the simulated robots (sim/mjcf.py).
TURTLEBOT2_MAX_LINEAR_SPEED = 0.7  # m/s
TURTLEBOT2_MAX_ANGULAR_SPEED = math.pi  # rad/s
TURTLEBOT2_RADIUS = 0.177  # m

#: How long the body waits at start for the first Odometry, in s.
ODOMETRY_WAIT_S = 10.0

#: The same warning about a topic's messages is logged at most once in this many s.
WARNING_PERIOD_S = 5.0


def import_or_explain(module: str, unavailable: type[ImportError], hint: str):
    """`module` (rospy, rclpy: they come with ROS, not from PyPI), or `unavailable` naming what to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise unavailable(f"cannot import {module} ({exc}). {hint}") from exc


def quaternion_msg_to_yaw(q) -> float:
    """Yaw in rad of a geometry_msgs/Quaternion (roll and pitch ignored)."""
    return quaternion_to_yaw(q.x, q.y, q.z, q.w)


def pose_msg_to_pose2d(pose) -> Pose2D:
    """A geometry_msgs/Pose as a planar Pose2D (x, y in m, yaw in rad)."""
    return Pose2D(float(pose.position.x), float(pose.position.y), quaternion_msg_to_yaw(pose.orientation))


def odometry_from_msg(msg) -> tuple[Pose2D, float, float] | None:
    """(pose, v, w) of a nav_msgs/Odometry, or None when any of them is not finite (a driver's NaN
    must not reach the brain: it would be planned on, and sent)."""
    if not finite_pose_msg(msg.pose.pose):
        return None
    v, w = float(msg.twist.twist.linear.x), float(msg.twist.twist.angular.z)
    if not (math.isfinite(v) and math.isfinite(w)):
        return None
    return pose_msg_to_pose2d(msg.pose.pose), v, w


def finite_pose_msg(pose) -> bool:
    """Whether a geometry_msgs/Pose's position and orientation are all finite."""
    p, q = pose.position, pose.orientation
    return all(math.isfinite(float(v)) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w))


def laser_scan_from_msg(msg, origin: Pose2D, stamp: float) -> LaserScan | None:
    """A sensor_msgs/LaserScan as rescuemesh.body.LaserScan taken from `origin` at `stamp` s, or None
    for a scan whose geometry (angle_min, angle_increment, range_min, range_max) or origin is not
    finite, or whose range_min > range_max.

    REP-117: a beam with no return is +inf or beyond range_max, one too close is -inf or below
    range_min; NaN is a bad reading. Everything without a valid return becomes inf (the brain
    reads inf as "free to range_max"); readings below range_min stay, LaserScan.points_in_map drops them.
    """
    geometry = (float(msg.angle_min), float(msg.angle_increment), float(msg.range_min), float(msg.range_max),
                origin.x, origin.y, origin.yaw, stamp)
    if not all(math.isfinite(value) for value in geometry) or geometry[2] > geometry[3]:
        return None
    ranges = np.asarray(msg.ranges, dtype=float).copy()
    range_max = float(msg.range_max)
    ranges[np.isnan(ranges) | (ranges > range_max)] = np.inf
    return LaserScan(stamp=stamp, origin=origin, angle_min=float(msg.angle_min),
                     angle_increment=float(msg.angle_increment), range_min=float(msg.range_min),
                     range_max=range_max, ranges=ranges)


def compose(pose: Pose2D, offset: Pose2D) -> Pose2D:
    """`offset` (in `pose`'s frame) expressed in the frame `pose` is in."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return Pose2D(pose.x + c * offset.x - s * offset.y, pose.y + s * offset.x + c * offset.y, pose.yaw + offset.yaw)


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
        self._warned: dict[str, float] = {}  # warning -> when it was last logged (time.monotonic)

    @abc.abstractmethod
    def _ros_seconds(self) -> float:
        """The ROS clock, in s."""

    @abc.abstractmethod
    def _ros_running(self) -> bool:
        """False once the node is shut down."""

    @abc.abstractmethod
    def _no_odometry_hint(self) -> str:
        """What to check when no Odometry arrives."""

    @abc.abstractmethod
    def _topic(self, which: str) -> str:
        """The resolved name of the "odom", "pose" or "scan" topic, for warnings."""

    @abc.abstractmethod
    def _log_warning(self, text: str) -> None:
        """A warning through the middleware's logger (rosout)."""

    @abc.abstractmethod
    def _scan_stamp(self, msg) -> float:
        """A LaserScan's time on the brain's clock (s): its header's, or its receipt's when the driver left it 0."""

    laser_offset: Pose2D

    # ----- the middleware's threads -----

    def _warn(self, text: str) -> None:
        """`text` logged, at most once per WARNING_PERIOD_S (a driver's bad messages come at its rate)."""
        now = time.monotonic()
        with self._lock:
            if now - self._warned.get(text, -math.inf) < WARNING_PERIOD_S:
                return
            self._warned[text] = now
        self._log_warning(text)

    def _on_odom(self, msg) -> None:
        odom = odometry_from_msg(msg)
        if odom is None:  # refused: the last good odometry stays (and ages: odometry_age)
            self._warn(f"{self.name}: odometry on {self._topic('odom')} is not finite: ignored")
            return
        with self._lock:
            self._odom, self._odom_received_s = odom, self._ros_seconds()
        self._odometry_arrived.set()

    def _on_pose(self, msg) -> None:
        if not finite_pose_msg(msg.pose.pose):
            self._warn(f"{self.name}: pose on {self._topic('pose')} is not finite: ignored")
            return
        pose = pose_msg_to_pose2d(msg.pose.pose)
        with self._lock:
            self._localised = pose

    def _on_scan(self, msg) -> None:
        with self._lock:
            base = self._localised if self._localised is not None else (self._odom[0] if self._odom else None)
        if base is None:
            return  # no pose to place it at yet
        scan = laser_scan_from_msg(msg, compose(base, self.laser_offset), self._scan_stamp(msg))
        if scan is None:
            self._warn(f"{self.name}: scan on {self._topic('scan')} has a geometry that is not finite: ignored")
            return
        with self._lock:
            self._scan = scan

    # ----- the runtime's thread -----

    def wait_for_odometry(self, timeout_s: float) -> None:
        """Block until an Odometry has arrived, or raise NoOdometryError after `timeout_s` s (wall time)."""
        deadline = time.monotonic() + timeout_s
        while not self._odometry_arrived.wait(0.1):
            if not self._ros_running() or time.monotonic() >= deadline:
                raise NoOdometryError(
                    f"{self.name}: no {self.odometry_type} on {self._topic('odom')} within {timeout_s:g} s: "
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
            raise NoOdometryError(f"{self.name}: no {self.odometry_type} on {self._topic('odom')} yet")
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
