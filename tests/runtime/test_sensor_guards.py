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


def test_a_ros2_body_refuses_odometry_a_pose_and_a_scan_that_are_not_finite():
    # the ROS 2 body used to take Odometry and scans as they came (NaN included); its callbacks now
    # use the same conversions as ROS 1's and warn (callbacks called on a stand-in, without rclpy)
    import threading

    from rescuemesh.runtime.ros.ros2_body import Ros2Body

    warnings = []
    body = NS(_warn=warnings.append, resolved={"odom": "/r/odom", "pose": "/r/pose", "scan": "/r/scan"},
              _lock=threading.Lock(), _odom=None, _odom_received_s=None, _localised=None, _scan=None,
              _odometry_arrived=threading.Event(), ros=NS(seconds=lambda: 3.0), time_origin=0.0,
              laser_offset=Pose2D(0.0, 0.0, 0.0))
    Ros2Body._on_odom(body, odometry(x=math.nan))
    assert body._odom is None and not body._odometry_arrived.is_set() and "not finite" in warnings[-1]
    Ros2Body._on_odom(body, odometry())
    assert body._odom[0].x == 1.0 and body._odometry_arrived.is_set()
    Ros2Body._on_pose(body, NS(pose=odometry(qw=math.inf).pose))
    assert body._localised is None and "/r/pose" in warnings[-1]
    Ros2Body._on_scan(body, NS(header=NS(stamp=NS(sec=1, nanosec=0)), **vars(scan(angle_min=math.nan))))
    assert body._scan is None and "/r/scan" in warnings[-1]
    Ros2Body._on_scan(body, NS(header=NS(stamp=NS(sec=1, nanosec=0)), **vars(scan())))
    assert body._scan is not None
