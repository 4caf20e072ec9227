"""KinematicBody: a unicycle on a fake clock, its limits, and its lidar ray-cast on a grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import Costmap, GoalStatus, NavigateToPose
from rescuemesh.runtime.onboard.kinematic_body import MAX_LINEAR_SPEED, KinematicBody, empty_grid


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def walled_grid() -> OccupancyGrid:
    """10 m x 10 m at 0.05 m from (-5, -5), a wall filling x >= 2 m."""
    occupied = np.zeros((200, 200), dtype=bool)
    occupied[:, 140:] = True  # col 140 starts at x = -5 + 140 * 0.05 = 2.0
    return OccupancyGrid(occupied, 0.05, -5.0, -5.0)


def test_straight_line_at_the_commanded_speed():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(1.0, 2.0, 0.0), clock)
    body.set_velocity(0.5, 0.0)
    clock.t = 2.0
    pose, v, w = body.odometry()
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((2.0, 2.0, 0.0))
    assert (v, w) == (0.5, 0.0)
    assert body.distance_m == pytest.approx(1.0)


def test_arc_is_exact_over_a_long_gap():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(0.0, 0.0, 0.0), clock)
    body.set_velocity(0.5, 0.5)  # radius 1 m, anticlockwise
    clock.t = 2 * math.pi  # half a turn (0.5 rad/s for 2 pi s) in one call: the loop stalled
    pose = body.pose()
    assert (pose.x, pose.y) == pytest.approx((0.0, 2.0), abs=1e-9)
    assert abs(abs(pose.yaw) - math.pi) < 1e-9


def test_twist_applies_from_the_moment_it_is_set():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(0.0, 0.0, 0.0), clock)
    body.set_velocity(0.4, 0.0)
    clock.t = 1.0
    body.set_velocity(0.0, 0.0)  # this used to be easy to get wrong: the old twist must cover [0, 1]
    clock.t = 5.0
    assert body.pose().x == pytest.approx(0.4)


def test_limits_clock_going_back_and_nan():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(0.0, 0.0, 0.0), clock)
    body.set_velocity(10.0, -100.0)
    _, v, w = body.odometry()
    assert v == MAX_LINEAR_SPEED and w == -body.max_angular_speed
    body.set_velocity(float("nan"), 1.0)
    assert body.odometry()[1:] == (0.0, 0.0)
    body.set_velocity(0.5, 0.0)
    clock.t = -1.0  # a clock that goes back moves nothing
    assert body.pose() == Pose2D(0.0, 0.0, 0.0)


def test_no_grid_no_scan():
    assert KinematicBody("robot_1", Pose2D(0, 0), Clock()).scan() is None


def test_scan_sees_the_wall_ahead_and_not_behind():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(0.0, 0.0, 0.0), clock, grid=walled_grid())
    scan = body.scan()
    ahead = int(np.argmin(np.abs(scan.angles())))
    assert scan.ranges[ahead] == pytest.approx(2.0, abs=0.05)
    points = scan.points_in_map()
    on_wall = points[:, 0] >= 1.95
    on_edge = (np.abs(points[:, 1]) >= 4.95) | (points[:, 0] <= -4.95)  # off the grid counts as an obstacle
    assert on_wall.sum() > 50 and np.all(on_wall | on_edge)
    body.set_velocity(0.0, 1.0)
    clock.t = math.pi  # now facing -x: the wall is behind, the grid edge 5 m ahead
    rear = body.scan()
    ahead = int(np.argmin(np.abs(rear.angles())))
    assert rear.ranges[ahead] == pytest.approx(5.0, abs=0.05)


def test_scan_is_a_new_sweep_ten_times_a_second():
    clock = Clock()
    body = KinematicBody("robot_1", Pose2D(0.0, 0.0, 0.0), clock, grid=walled_grid())
    first = body.scan()
    clock.t = 0.05
    assert body.scan() is first
    clock.t = 0.1
    assert body.scan().stamp == pytest.approx(0.1)


def test_empty_grid_is_free_inside_and_lethal_outside():
    grid = empty_grid(1.0, -1.0, size_m=4.0, resolution=0.1)
    assert grid.shape == (40, 40)
    assert not grid.is_occupied(1.0, -1.0) and not grid.is_occupied(2.9, 0.9)
    assert grid.is_occupied(3.1, -1.0)
    with pytest.raises(ValueError):
        empty_grid(size_m=0.0)


def test_the_navigator_drives_it_to_a_goal():
    clock = Clock()
    grid = empty_grid(size_m=10.0)
    body = KinematicBody("robot_1", Pose2D(-2.0, 0.0, 0.0), clock, grid=grid)
    nav = NavigateToPose(Costmap(grid))
    nav.send_goal(Pose2D(2.0, 1.0, 0.0), 0.0, check_yaw=False)
    result = None
    while clock.t < 30.0 and result is None:
        body.set_velocity(*nav.step(clock.t, body.pose(), body.scan()))
        result = nav.next_result()
        clock.t = round(clock.t + 0.05, 9)
    assert result is not None and result.status is GoalStatus.SUCCEEDED
    assert body.pose().distance_to(Pose2D(2.0, 1.0)) < 0.2
