"""The command-line options of a robot process on a ROS body (`rescuemesh robot --body ros1|ros2`): topic
names, the pose source (odometry, or an AMCL-style pose topic in the map frame), the laser's mount, speed
limits, TwistStamped; and the ROS 2 arguments after `--ros-args`.

Owns: the flags, their checks (one line each, as UsageError) and the bodies' keyword arguments built from
them; the map-frame warning. Must not know: rospy or rclpy (the bodies import those), the brain.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

#: What a robot without a pose topic says once at start (robots that command each other need one frame).
MAP_FRAME_WARNING = (
    "{name}: warning: no --pose-topic, so {name}'s odometry frame ({odom}) is taken as the map frame. Robots "
    "that command each other (Follow, Goto, MoveAround) exchange poses in one shared map frame: unless every "
    "robot's odometry starts in that frame (Gazebo's world-aligned odometry, robots started at known poses "
    "with matching --start), give each robot --pose-topic amcl_pose with AMCL on one shared map "
    "(docs/ros2.md, 'One map frame').")


def split_ros_args(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """(rescuemesh's arguments, ROS 2's): everything after `--ros-args` is rclpy's (remapping `-r`,
    parameters `-p`, `--log-level`, ...), as on any ROS 2 node's command line."""
    argv = list(argv)
    if "--ros-args" in argv:
        at = argv.index("--ros-args")
        return argv[:at], argv[at + 1:]
    return argv, []


def add_ros_arguments(p: argparse.ArgumentParser) -> None:
    """The ROS body flags (for --body ros1 and ros2)."""
    g = p.add_argument_group("ROS bodies (--body ros1 or ros2)",
                             "topic names: ros1 takes names with {robot} for the robot's name (default /{robot}/odom ...); "
                             "ros2 takes ROS 2 names, relative ones in the node's namespace (default /ROBOT: odom -> "
                             "/robot_2/odom), and remapping after --ros-args (-r odom:=/odom, -r __ns:=/tb4, "
                             "-p use_sim_time:=true)")
    g.add_argument("--odom-topic", default=None, metavar="TOPIC", help="nav_msgs Odometry in (default ros1 /{robot}/odom, ros2 odom)")
    g.add_argument("--scan-topic", default=None, metavar="TOPIC", help="sensor_msgs LaserScan in (default ros1 /{robot}/scan, ros2 scan)")
    g.add_argument("--cmd-vel-topic", default=None, metavar="TOPIC", help="geometry_msgs Twist out (default ros1 /{robot}/cmd_vel, ros2 cmd_vel)")
    g.add_argument("--pose-topic", default=None, metavar="TOPIC",
                   help="pose source: a geometry_msgs PoseWithCovarianceStamped topic in the map frame (AMCL's "
                        "amcl_pose); default: the odometry's pose, its frame taken as the map frame")
    g.add_argument("--laser-mount", default="0,0,0", metavar="X,Y[,YAW]",
                   help="the laser's pose in the base frame, m and rad (default 0,0,0; ros2: parameters laser_x, "
                        "laser_y, laser_yaw override it)")
    g.add_argument("--max-linear-speed", type=float, default=None, metavar="M_S",
                   help="clamp cmd_vel's linear.x to this, m/s (default 0.7, a TurtleBot 2)")
    g.add_argument("--max-angular-speed", type=float, default=None, metavar="RAD_S",
                   help="clamp cmd_vel's angular.z to this, rad/s (default pi)")
    g.add_argument("--twist-stamped", action="store_true",
                   help="ros2: publish geometry_msgs/msg/TwistStamped (diff_drive_controller on Jazzy and later)")
    g.add_argument("--namespace", default=None, metavar="NS",
                   help="ros2: the node's namespace (default /ROBOT); --ros-args -r __ns:=NS does the same")


def ros_body_options(args: argparse.Namespace, usage_error) -> dict:
    """The checked ROS flags as a dict (raises `usage_error(text)` for a bad one)."""
    from rescuemesh.runtime.onboard.linked_robot import parse_pose  # the same X,Y[,YAW] reading as --start

    laser = parse_pose(args.laser_mount, "--laser-mount")
    for flag, value in (("--max-linear-speed", args.max_linear_speed), ("--max-angular-speed", args.max_angular_speed)):
        if value is not None and not (math.isfinite(value) and 0 < value <= 10):
            raise usage_error(f"{flag} must be in (0, 10], got {value}")
    for flag, value in (("--odom-topic", args.odom_topic), ("--scan-topic", args.scan_topic),
                        ("--cmd-vel-topic", args.cmd_vel_topic), ("--pose-topic", args.pose_topic),
                        ("--namespace", args.namespace)):
        if value is not None and (not value or any(c.isspace() for c in value)):
            raise usage_error(f"{flag} takes a topic name without spaces, got {value!r}")
    if args.body not in ("ros1", "ros2"):
        given = [f for f, v in (("--odom-topic", args.odom_topic), ("--scan-topic", args.scan_topic),
                                ("--cmd-vel-topic", args.cmd_vel_topic), ("--pose-topic", args.pose_topic),
                                ("--namespace", args.namespace), ("--max-linear-speed", args.max_linear_speed),
                                ("--max-angular-speed", args.max_angular_speed)) if v is not None]
        if args.twist_stamped:
            given.append("--twist-stamped")
        if args.laser_mount != "0,0,0":
            given.append("--laser-mount")
        if given:
            raise usage_error(f"{', '.join(given)}: only for --body ros1 or ros2")
    if args.body == "ros1" and (args.twist_stamped or args.namespace is not None):
        raise usage_error("--twist-stamped and --namespace are for --body ros2")
    return {"odom_topic": args.odom_topic, "scan_topic": args.scan_topic, "cmd_vel_topic": args.cmd_vel_topic,
            "pose_topic": args.pose_topic, "laser_mount": laser, "max_linear_speed": args.max_linear_speed,
            "max_angular_speed": args.max_angular_speed, "twist_stamped": args.twist_stamped,
            "namespace": args.namespace}


def _limits(ros: dict) -> dict:
    limits = {}
    if ros["max_linear_speed"] is not None:
        limits["max_linear_speed"] = ros["max_linear_speed"]
    if ros["max_angular_speed"] is not None:
        limits["max_angular_speed"] = ros["max_angular_speed"]
    return limits


def ros1_body_kwargs(ros: dict) -> dict:
    """Ros1Body's keyword arguments (topics, laser_offset, limits) from the flags."""
    from rescuemesh.runtime.ros.ros1_body import Ros1Topics

    default = Ros1Topics()
    topics = Ros1Topics(ros["odom_topic"] or default.odom, ros["scan_topic"] or default.scan,
                        ros["cmd_vel_topic"] or default.cmd_vel, ros["pose_topic"])
    return {"topics": topics, "laser_offset": ros["laser_mount"], **_limits(ros)}


def ros2_body_kwargs(ros: dict) -> dict:
    """Ros2Body's keyword arguments (topics, laser_offset, limits) from the flags."""
    from rescuemesh.runtime.ros.ros2_body import Ros2Topics

    default = Ros2Topics()
    topics = Ros2Topics(ros["odom_topic"] or default.odom, ros["scan_topic"] or default.scan,
                        ros["cmd_vel_topic"] or default.cmd_vel, ros["pose_topic"], ros["twist_stamped"])
    return {"topics": topics, "laser_offset": ros["laser_mount"], **_limits(ros)}


def map_frame_warning(name: str, ros: dict, odom_topic: str) -> str | None:
    """The warning a robot without a pose topic prints at start, or None when it has one."""
    if ros["pose_topic"] is not None:
        return None
    return MAP_FRAME_WARNING.format(name=name, odom=odom_topic)

