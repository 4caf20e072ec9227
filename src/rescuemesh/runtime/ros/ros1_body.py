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

from dataclasses import dataclass

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.ros.ros_body_common import (  # the conversions' and limits' old home: their names stay
    ODOMETRY_WAIT_S,
    TURTLEBOT2_MAX_ANGULAR_SPEED,
    TURTLEBOT2_MAX_LINEAR_SPEED,
    TURTLEBOT2_RADIUS,
    NoOdometryError,
    RosBodyState,
    compose,
    finite_pose_msg,
    import_or_explain,
    laser_scan_from_msg,
    odometry_from_msg,
    pose_msg_to_pose2d,
    quaternion_msg_to_yaw,
)

__all__ = ["NoOdometryError", "Ros1Body", "Ros1Topics", "Ros1Unavailable", "ODOMETRY_WAIT_S",
           "TURTLEBOT2_MAX_ANGULAR_SPEED", "TURTLEBOT2_MAX_LINEAR_SPEED", "TURTLEBOT2_RADIUS", "compose",
           "finite_pose_msg", "laser_scan_from_msg", "odometry_from_msg", "pose_msg_to_pose2d",
           "quaternion_msg_to_yaw"]

ROS1_INSTALL_HINT = ("ROS 1's Python client is not on PyPI: install it with your ROS (Debian 12: "
                     "apt-get install ros-core python3-rospy python3-genpy python3-nav-msgs python3-sensor-msgs "
                     "python3-geometry-msgs ros-std-msgs ros-geometry-msgs) and run rescuemesh from a "
                     "virtualenv made with --system-site-packages (docs/ros1.md)")


class Ros1Unavailable(ImportError):
    """rospy or the ROS message packages cannot be imported: ROS 1 is not installed or not visible."""


def import_rospy():
    """rospy, or Ros1Unavailable naming what to install."""
    return import_or_explain("rospy", Ros1Unavailable, ROS1_INSTALL_HINT)


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

    # ----- what the shared callbacks ask (rospy's threads) -----

    def _scan_stamp(self, msg) -> float:
        stamp = msg.header.stamp.to_sec()
        return (stamp if stamp > 0.0 else self._rospy.get_time()) - self.time_origin

    def _log_warning(self, text: str) -> None:
        self._rospy.logwarn(text)

    def _topic(self, which: str) -> str:
        return getattr(self.topics, which)

    # ----- the Body interface (the runtime's thread) -----

    def _ros_seconds(self) -> float:
        return self._rospy.get_time()

    def _ros_running(self) -> bool:
        return not self._rospy.is_shutdown()

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
