"""A Body over ROS 1 topics, so the same brain, navigation and protocol drive any ROS 1 robot or a
Gazebo TurtleBot: nav_msgs/Odometry and sensor_msgs/LaserScan in, geometry_msgs/Twist out.

Owns: Ros1Topics (the topic names, configurable), Ros1Body (the latest odometry, localised pose and
scan, kept under a lock because rospy calls back on its own threads; set_velocity publishes a
Twist), the conversions quaternion -> yaw and sensor_msgs/LaserScan -> rescuemesh.body.LaserScan,
and init_node. Must not know: the brain, the protocol, the mesh, the loop that steps them (the
runtime owns time: `now()` is ROS time since the body was made, the clock brain.step is given).
rospy comes from ROS 1 (Debian: python3-rospy), not from PyPI; it is imported on first use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, quaternion_to_yaw
from rescuemesh.runtime.ros.ros_body_common import NoOdometryError, RosBodyState

__all__ = ["NoOdometryError", "Ros1Body", "Ros1Topics", "Ros1Unavailable"]  # NoOdometryError: its old home

#: TurtleBot 2 (Kobuki) limits and footprint, as the simulated robots (sim/mjcf.py).
TURTLEBOT2_MAX_LINEAR_SPEED = 0.7  # m/s
TURTLEBOT2_MAX_ANGULAR_SPEED = math.pi  # rad/s
TURTLEBOT2_RADIUS = 0.177  # m

#: How long the body waits at start for the first Odometry, in s.
ODOMETRY_WAIT_S = 10.0

ROS1_INSTALL_HINT = ("ROS 1's Python client is not on PyPI: install it with your ROS (Debian 12: "
                     "apt-get install ros-core python3-rospy python3-genpy python3-nav-msgs python3-sensor-msgs "
                     "python3-geometry-msgs ros-std-msgs ros-geometry-msgs) and run rescuemesh from a "
                     "virtualenv made with --system-site-packages (docs/ros1.md)")


class Ros1Unavailable(ImportError):
    """rospy or the ROS message packages cannot be imported: ROS 1 is not installed or not visible."""


def import_rospy():
    """rospy, or Ros1Unavailable naming what to install."""
    try:
        import rospy
    except ImportError as exc:
        raise Ros1Unavailable(f"cannot import rospy ({exc}). {ROS1_INSTALL_HINT}") from exc
    return rospy


def init_node(name: str) -> None:
    """Make this process a ROS node called `name` (once; a later call does nothing). rospy's own
    signal handlers are left out: the runtime decides how it stops."""
    rospy = import_rospy()
    if not rospy.core.is_initialized():
        rospy.init_node(name, anonymous=False, disable_signals=True)


@dataclass(frozen=True)
class Ros1Topics:
    """ROS 1 topic names of one robot; `{robot}` becomes the robot's name. The defaults are the
    issue's (`/robot_2/odom`, `/robot_2/scan`, `/robot_2/cmd_vel` for robot_2). `pose`: a
    geometry_msgs/PoseWithCovarianceStamped topic with the localised pose in the map frame (AMCL's
    `amcl_pose`); None (the default) takes the odometry's pose as the map pose (the odom frame is
    the map frame: right for Gazebo, drifting on a real base)."""

    odom: str = "/{robot}/odom"
    scan: str = "/{robot}/scan"
    cmd_vel: str = "/{robot}/cmd_vel"
    pose: str | None = None

    def resolve(self, robot: str) -> "Ros1Topics":
        """These names with `{robot}` replaced by `robot`."""
        fill = (lambda name: None if name is None else name.replace("{robot}", robot))
        return Ros1Topics(fill(self.odom), fill(self.scan), fill(self.cmd_vel), fill(self.pose))


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


class Ros1Body(RosBodyState):
    """A ground robot reached through ROS 1 topics (the node must be initialised: `init_node`).

    Reads the latest nav_msgs/Odometry (pose in the odom frame, twist in the base frame) and
    sensor_msgs/LaserScan, and, with `topics.pose`, the localised pose; `set_velocity` clamps to
    the limits and publishes a geometry_msgs/Twist. `laser_offset`: the laser's pose in the base
    frame (no TF lookup: give the mount). Construction waits up to `odometry_wait_s` for the first
    Odometry and raises NoOdometryError naming the topic when none comes.
    """

    def __init__(self, name: str, topics: Ros1Topics | None = None, *,
                 max_linear_speed: float = TURTLEBOT2_MAX_LINEAR_SPEED,
                 max_angular_speed: float = TURTLEBOT2_MAX_ANGULAR_SPEED, radius: float = TURTLEBOT2_RADIUS,
                 laser_offset: Pose2D = Pose2D(0.0, 0.0, 0.0), odometry_wait_s: float = ODOMETRY_WAIT_S,
                 time_origin: float | None = None) -> None:
        rospy = import_rospy()
        try:
            from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
            from nav_msgs.msg import Odometry
            from sensor_msgs.msg import LaserScan as ScanMsg
        except ImportError as exc:
            raise Ros1Unavailable(f"cannot import the ROS message packages ({exc}). {ROS1_INSTALL_HINT}") from exc
        self._rospy, self._twist = rospy, Twist
        self.name = name
        self.topics = (topics or Ros1Topics()).resolve(name)
        self.max_linear_speed, self.max_angular_speed, self.radius = max_linear_speed, max_angular_speed, radius
        self.laser_offset = laser_offset
        self._init_state(rospy.get_time() if time_origin is None else time_origin)
        self._cmd = rospy.Publisher(self.topics.cmd_vel, Twist, queue_size=1)
        self._subscribers = [rospy.Subscriber(self.topics.odom, Odometry, self._on_odom, queue_size=1),
                             rospy.Subscriber(self.topics.scan, ScanMsg, self._on_scan, queue_size=1)]
        if self.topics.pose is not None:
            self._subscribers.append(rospy.Subscriber(self.topics.pose, PoseWithCovarianceStamped, self._on_pose,
                                                      queue_size=1))
        self.wait_for_odometry(odometry_wait_s)

    # ----- rospy's threads -----

    def _stamp(self, header) -> float:
        """A message's time in the brain's clock (s); receipt time when the driver left it 0."""
        stamp = header.stamp.to_sec()
        return (stamp if stamp > 0.0 else self._rospy.get_time()) - self.time_origin

    def _on_odom(self, msg) -> None:
        odom = odometry_from_msg(msg)
        if odom is None:  # refused: the last good odometry stays (and ages: odometry_age)
            self._rospy.logwarn_throttle(5.0, f"{self.name}: odometry on {self.topics.odom} is not finite: ignored")
            return
        with self._lock:
            self._odom, self._odom_received_s = odom, self._rospy.get_time()
        self._odometry_arrived.set()

    def _on_pose(self, msg) -> None:
        if not finite_pose_msg(msg.pose.pose):
            self._rospy.logwarn_throttle(5.0, f"{self.name}: pose on {self.topics.pose} is not finite: ignored")
            return
        pose = pose_msg_to_pose2d(msg.pose.pose)
        with self._lock:
            self._localised = pose

    def _on_scan(self, msg) -> None:
        with self._lock:
            base = self._localised if self._localised is not None else (self._odom[0] if self._odom else None)
        if base is None:
            return  # no pose to place it at yet
        scan = laser_scan_from_msg(msg, compose(base, self.laser_offset), self._stamp(msg.header))
        if scan is None:
            self._rospy.logwarn_throttle(5.0, f"{self.name}: scan on {self.topics.scan} has a geometry that is not "
                                              "finite: ignored")
            return
        with self._lock:
            self._scan = scan

    # ----- the Body interface (the runtime's thread) -----

    def _ros_seconds(self) -> float:
        return self._rospy.get_time()

    def _ros_running(self) -> bool:
        return not self._rospy.is_shutdown()

    def _odometry_topic(self) -> str:
        return self.topics.odom

    def _no_odometry_hint(self) -> str:
        return "is the robot (or Gazebo) running, is ROS_MASTER_URI right, is the topic name right?"

    def set_velocity(self, linear: float, angular: float) -> None:
        twist = self._twist()
        twist.linear.x, twist.angular.z = self._clamped(linear, angular)
        self._cmd.publish(twist)

    def close(self) -> None:
        """Stop the wheels (a zero Twist) and leave the topics."""
        try:
            self.set_velocity(0.0, 0.0)
        finally:
            for subscriber in self._subscribers:
                subscriber.unregister()
            self._cmd.unregister()
