import math

import pytest

from rescuemesh.geometry import Pose2D, quaternion_to_yaw, wrap_angle
from rescuemesh.robot.behaviours import circle_waypoints
from rescuemesh.robot.naming import command_topic, robot_address, robot_name


def test_twenty_waypoints_evenly_spaced_anticlockwise_and_closed():
    center = Pose2D(2.0, 3.0)
    points = circle_waypoints(center, 1.5, 20, start_near=Pose2D(3.5, 3.0))
    assert len(points) == 21 and points[0].pose == points[-1].pose
    angles = [math.atan2(p.pose.y - 3.0, p.pose.x - 2.0) for p in points]
    steps = [wrap_angle(b - a) for a, b in zip(angles, angles[1:])]
    assert steps == pytest.approx([2 * math.pi / 20] * 20)  # equal and positive: anticlockwise
    for p in points:
        assert p.pose.distance_to(center) == pytest.approx(1.5)


def test_first_waypoint_is_the_one_nearest_the_robot():
    points = circle_waypoints(Pose2D(0, 0), 2.0, 20, start_near=Pose2D(0.1, -5.0))
    assert (points[0].pose.x, points[0].pose.y) == pytest.approx((0.0, -2.0), abs=1e-9)


def test_heading_is_the_tangent_and_matches_its_quaternion():
    for p in circle_waypoints(Pose2D(0, 0), 1.0, 20, start_near=Pose2D(1, 0)):
        radial = math.atan2(p.pose.y, p.pose.x)
        assert wrap_angle(p.pose.yaw - radial) == pytest.approx(math.pi / 2)
        assert wrap_angle(quaternion_to_yaw(*p.quaternion) - p.pose.yaw) == pytest.approx(0.0, abs=1e-9)


def test_robot_names_and_addresses():
    assert robot_address("robot_2") == 2 and robot_name(2) == "robot_2"
    assert command_topic("robot_2") == "robot_2/comm_protocol/command"


@pytest.mark.parametrize("name", ["robot_0", "robot_255", "robot", "Robot_1", "robot_1x", "r2d2", ""])
def test_unknown_robot_names_are_refused(name):
    with pytest.raises(ValueError, match="unknown robot"):
        robot_address(name)
