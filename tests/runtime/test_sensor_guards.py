"""A ROS 1 robot's sensors at the body: odometry or a scan that is not finite is refused before it
reaches the brain (pure conversions, without ROS: messages as plain objects)."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.ros.ros1_body import laser_scan_from_msg, odometry_from_msg


def odometry(x=1.0, y=2.0, qz=0.0, qw=1.0, v=0.2, w=0.1):
    pose = NS(position=NS(x=x, y=y, z=0.0), orientation=NS(x=0.0, y=0.0, z=qz, w=qw))
    return NS(pose=NS(pose=pose), twist=NS(twist=NS(linear=NS(x=v), angular=NS(z=w))))


def scan(**fields):
    values = dict(angle_min=-1.0, angle_increment=0.5, range_min=0.1, range_max=5.0, ranges=[1.0, math.nan, 9.0])
    values.update(fields)
    return NS(**values)


def test_finite_odometry_passes():
    pose, v, w = odometry_from_msg(odometry())
    assert (pose.x, pose.y, v, w) == (1.0, 2.0, 0.2, 0.1)


@pytest.mark.parametrize("field", ["x", "y", "qz", "qw", "v", "w"])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_odometry_that_is_not_finite_is_refused(field, bad):
    # this used to hand a NaN pose to the brain, which planned on it and sent it (EncodeError)
    assert odometry_from_msg(odometry(**{field: bad})) is None


def test_a_scan_with_nan_readings_keeps_them_as_no_return():
    got = laser_scan_from_msg(scan(), Pose2D(0.0, 0.0, 0.0), 1.0)
    assert got is not None and list(got.ranges[1:]) == [math.inf, math.inf]  # REP-117: NaN is a bad reading


@pytest.mark.parametrize("fields", [dict(angle_min=math.nan), dict(angle_increment=math.inf),
                                   dict(range_min=math.nan), dict(range_max=math.nan),
                                   dict(range_min=6.0)], ids=str)
def test_a_scan_whose_geometry_is_not_finite_is_refused(fields):
    assert laser_scan_from_msg(scan(**fields), Pose2D(0.0, 0.0, 0.0), 1.0) is None


def test_a_scan_taken_from_a_pose_that_is_not_finite_is_refused():
    assert laser_scan_from_msg(scan(), Pose2D(math.nan, 0.0, 0.0), 1.0) is None


def _standing_in(version: str, warnings: list):
    """A ROS 1 or ROS 2 body with its middleware replaced by plain objects (no rospy, no rclpy)."""
    if version == "ros1":
        from rescuemesh.runtime.ros.ros1_body import Ros1Body, Ros1Topics

        body = object.__new__(Ros1Body)
        body.topics = Ros1Topics(pose="/{robot}/pose").resolve("r")
        body._rospy = NS(get_time=lambda: 3.0, logwarn=warnings.append)
    else:
        from rescuemesh.runtime.ros.ros2_body import Ros2Body

        body = object.__new__(Ros2Body)
        body.resolved = {"odom": "/r/odom", "pose": "/r/pose", "scan": "/r/scan"}
        body.ros = NS(seconds=lambda: 3.0, node=NS(get_logger=lambda: NS(warning=warnings.append)))
    body.name, body.laser_offset = "r", Pose2D(0.0, 0.0, 0.0)
    body._init_state(0.0)
    return body


def _scan_msg(**fields):
    return NS(header=NS(stamp=NS(sec=1, nanosec=0, to_sec=lambda: 1.0)), **vars(scan(**fields)))


@pytest.mark.parametrize("version", ["ros1", "ros2"])
def test_a_ros_body_refuses_odometry_a_pose_and_a_scan_that_are_not_finite(version):
    # the ROS 2 body used to take Odometry and scans as they came (NaN included); both bodies' callbacks
    # are now one (ros_body_common.RosBodyState), called here on bodies whose middleware is stood in for
    warnings = []
    body = _standing_in(version, warnings)
    body._on_odom(odometry(x=math.nan))
    assert body._odom is None and not body._odometry_arrived.is_set()
    assert warnings == ["r: odometry on /r/odom is not finite: ignored"]
    body._on_odom(odometry())
    assert body._odom[0].x == 1.0 and body._odometry_arrived.is_set() and body.odometry_age() == 0.0
    body._on_pose(NS(pose=odometry(qw=math.inf).pose))
    assert body._localised is None and warnings[-1] == "r: pose on /r/pose is not finite: ignored"
    body._on_scan(_scan_msg(angle_min=math.nan))
    assert body._scan is None and warnings[-1] == "r: scan on /r/scan has a geometry that is not finite: ignored"
    body._on_scan(_scan_msg())
    assert body._scan is not None and body._scan.stamp == 1.0  # the header's stamp on the brain's clock


@pytest.mark.parametrize("version", ["ros1", "ros2"])
def test_a_driver_that_keeps_sending_bad_odometry_is_warned_about_once_per_period(version):
    warnings = []
    body = _standing_in(version, warnings)
    for _ in range(50):  # a 50 Hz driver's second of NaN odometry
        body._on_odom(odometry(x=math.nan))
    body._on_scan(_scan_msg())  # no pose yet: nothing to place it at, no warning
    body._on_pose(NS(pose=odometry(qw=math.inf).pose))
    assert warnings == ["r: odometry on /r/odom is not finite: ignored", "r: pose on /r/pose is not finite: ignored"]
