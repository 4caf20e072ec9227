"""Ros1Body: the conversions from ROS messages, and the error when a robot sends no odometry."""

import math

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.ros.ros1_body import Ros1Topics, compose, laser_scan_from_msg, pose_msg_to_pose2d

pytestmark = pytest.mark.ros1


@pytest.mark.parametrize("yaw", [0.0, 0.5, -1.2, math.pi - 1e-6, -math.pi / 2])
def test_pose_and_yaw_from_geometry_msgs(ros1_installed, yaw):
    from geometry_msgs.msg import Pose

    msg = Pose()
    msg.position.x, msg.position.y = 1.5, -2.0
    msg.orientation.z, msg.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    pose = pose_msg_to_pose2d(msg)
    assert (pose.x, pose.y) == (1.5, -2.0)
    assert math.isclose(pose.yaw, yaw, abs_tol=1e-9)


def test_laser_scan_from_sensor_msgs(ros1_installed):
    from sensor_msgs.msg import LaserScan

    msg = LaserScan()
    msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max = -0.1, 0.1, 0.12, 3.5
    msg.ranges = [1.0, float("nan"), float("inf"), 9.0, 0.05]
    scan = laser_scan_from_msg(msg, Pose2D(1.0, 2.0, math.pi / 2), stamp=4.25)
    assert scan.stamp == 4.25 and scan.origin == Pose2D(1.0, 2.0, math.pi / 2)
    # a bad reading (NaN) and one beyond range_max are "no return"; too close stays and is dropped as a point
    assert scan.ranges[0] == pytest.approx(1.0) and np.isinf(scan.ranges[1:4]).all() and scan.ranges[4] == 0.05
    points = scan.points_in_map()  # the one valid return: beam 0 at -0.1 rad, 1 m, from a robot facing +y
    assert points.shape == (1, 2)
    assert points[0] == pytest.approx([1.0 + math.cos(math.pi / 2 - 0.1), 2.0 + math.sin(math.pi / 2 - 0.1)], abs=1e-5)


def test_laser_mount_offset_is_composed_with_the_pose():
    origin = compose(Pose2D(1.0, 1.0, math.pi / 2), Pose2D(0.2, 0.0, 0.0))
    assert (origin.x, origin.y, origin.yaw) == pytest.approx((1.0, 1.2, math.pi / 2))


def test_topic_names_are_the_issues_by_default_and_configurable():
    assert Ros1Topics().resolve("robot_2") == Ros1Topics("/robot_2/odom", "/robot_2/scan", "/robot_2/cmd_vel")
    custom = Ros1Topics(odom="/{robot}/wheel_odom", cmd_vel="/mobile_base/commands/velocity", pose="/amcl_pose")
    assert custom.resolve("robot_4") == Ros1Topics("/robot_4/wheel_odom", "/robot_4/scan",
                                                   "/mobile_base/commands/velocity", "/amcl_pose")


def test_no_odometry_is_a_clear_error_within_the_bound(ros):
    team = ros.team(["robot_7"], "--odometry-wait", "1")
    assert team.wait(30) == 3
    assert "robot_7: no nav_msgs/Odometry on /robot_7/odom within 1 s" in team.stderr()
