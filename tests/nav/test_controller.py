import math

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.nav import ControllerParams, compute_velocity, limit_acceleration
from rescuemesh.nav.controller import obstacle_clearance, obstacle_reach
from rescuemesh.nav.path import Polyline

P = ControllerParams()
ORIGIN = Pose2D(0.0, 0.0, 0.0)
STRAIGHT = np.array([[0.0, 0.0], [5.0, 0.0]])


def test_straight_path_drives_at_cruise_speed_without_turning():
    v, w = compute_velocity(ORIGIN, STRAIGHT, None, P)
    assert v == pytest.approx(P.max_linear)
    assert w == pytest.approx(0.0, abs=1e-9)


def test_heading_is_corrected_toward_the_path():
    v, w = compute_velocity(Pose2D(0.0, -0.2, 0.0), STRAIGHT, None, P)
    assert v > 0.0 and w > 0.0  # path on the left: turn left


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_path_behind_rotates_in_place_toward_it(side):
    path = np.array([[0.0, 0.0], [-3.0, side * 0.5]])
    v, w = compute_velocity(ORIGIN, path, None, P)
    assert v == 0.0
    assert math.copysign(1.0, w) == side and abs(w) >= P.min_rotate_speed


def test_obstacle_within_stop_distance_ahead_stops():
    ahead = np.array([[P.footprint_radius + 0.25, 0.05]])
    assert compute_velocity(ORIGIN, STRAIGHT, ahead, P)[0] == 0.0


def test_obstacle_at_0_7_m_slows_down():
    free_v = compute_velocity(ORIGIN, STRAIGHT, None, P)[0]
    v = compute_velocity(ORIGIN, STRAIGHT, np.array([[0.7, 0.0]]), P)[0]
    assert 0.0 < v < free_v


@pytest.mark.parametrize("point", [(0.6, 0.5), (0.6, -0.45), (-0.5, 0.0), (3.0, 0.0)])
def test_obstacle_outside_the_swept_corridor_does_not_slow(point):
    free = compute_velocity(ORIGIN, STRAIGHT, None, P)
    assert compute_velocity(ORIGIN, STRAIGHT, np.array([point]), P) == free


def test_obstacle_on_the_arc_counts_but_not_one_straight_ahead_off_it():
    radius = 0.8  # turning left around (0, 0.8)
    on_arc = np.array([[radius * math.sin(0.8), radius * (1 - math.cos(0.8))]])
    assert obstacle_clearance(on_arc, 1.0 / radius, P) < 0.5
    assert obstacle_clearance(np.array([[1.2, -0.1]]), 1.0 / radius, P) == math.inf


def test_tight_curves_are_driven_slower():
    curve = np.array([[0.0, 0.0], [0.3, 0.0], [0.5, 0.3], [0.5, 2.0]])
    v_curve = compute_velocity(ORIGIN, curve, None, P)[0]
    assert 0.0 < v_curve < P.max_linear


def test_slows_down_near_the_path_end():
    v = compute_velocity(ORIGIN, np.array([[0.0, 0.0], [0.3, 0.0]]), None, P)[0]
    assert P.min_approach_linear <= v < P.max_linear


def test_at_the_end_aligns_to_the_goal_yaw_or_stops():
    path = np.array([[0.0, 0.0], [0.05, 0.0]])
    assert compute_velocity(ORIGIN, path, None, P, xy_tolerance=0.15) == (0.0, 0.0)
    v, w = compute_velocity(ORIGIN, path, None, P, goal_yaw=-1.0, xy_tolerance=0.15)
    assert v == 0.0 and w < 0.0
    assert compute_velocity(Pose2D(0.0, 0.0, -1.0), path, None, P, goal_yaw=-1.0, xy_tolerance=0.15) == (0.0, 0.0)


def test_angular_speed_saturates_keeping_the_arc():
    params = ControllerParams(max_angular=0.5)
    path = np.array([[0.0, 0.0], [0.2, 0.0], [0.3, 0.3], [0.3, 2.0]])
    v, w = compute_velocity(ORIGIN, path, None, params)
    assert abs(w) == pytest.approx(0.5)
    v_free, w_free = compute_velocity(ORIGIN, path, None, ControllerParams(max_angular=10.0))
    assert w / v == pytest.approx(w_free / v_free)


def test_lookahead_shrinks_at_low_speed():
    path = np.array([[0.0, 0.0], [0.4, 0.0], [0.4, 2.0]])
    slow = compute_velocity(ORIGIN, path, None, P, current_speed=0.0)
    fast = compute_velocity(ORIGIN, path, None, P, current_speed=0.5)
    assert slow[1] < fast[1]  # at 0.4 m the corner is not yet in view; at 0.6 m it is


def test_acceleration_limit_applies_to_speeding_up_only():
    assert limit_acceleration(0.5, 0.0, 0.05, P) == pytest.approx(0.05)
    assert limit_acceleration(0.0, 0.5, 0.05, P) == 0.0
    assert limit_acceleration(0.5, 0.0, 0.05, ControllerParams(max_linear_accel=None)) == 0.5


def test_empty_path_gives_zero():
    assert compute_velocity(ORIGIN, np.zeros((0, 2)), None, P) == (0.0, 0.0)


def test_obstacle_beyond_the_path_end_does_not_stop_short_of_the_goal():
    # this used to stop the robot 0.48 m short of any obstacle, so goals near walls were unreachable
    path = np.array([[0.0, 0.0], [0.5, 0.0]])
    wall_beyond = np.array([[0.5 + P.footprint_radius + 0.12, 0.0]])
    assert compute_velocity(ORIGIN, path, wall_beyond, P) == compute_velocity(ORIGIN, path, None, P)
    before_end = np.array([[0.45, 0.0]])
    assert compute_velocity(ORIGIN, path, before_end, P)[0] == 0.0


def test_a_polyline_path_gives_the_same_command_as_the_array():
    curve = np.array([[0.0, 0.0], [0.3, 0.0], [0.5, 0.3], [0.5, 2.0]])
    scan = np.array([[0.6, 0.4], [0.9, 0.2], [-0.3, 0.1]])
    for pose in (ORIGIN, Pose2D(0.1, -0.1, 0.4), Pose2D(0.45, 0.5, 1.5)):
        assert compute_velocity(pose, Polyline.from_points(curve), scan, P) == compute_velocity(pose, curve, scan, P)


def test_scan_points_beyond_the_obstacle_reach_cannot_change_the_command():
    rng = np.random.default_rng(3)
    reach = obstacle_reach(P)
    far = rng.uniform(-4.0, 4.0, size=(400, 2))
    far = far[np.hypot(far[:, 0], far[:, 1]) > reach]
    for curvature in (0.0, 0.5, -1.5, 4.0):
        assert obstacle_clearance(far, curvature, P) > max(P.obstacle_slow_distance, P.obstacle_stop_distance)
    near = np.array([[0.8, 0.05]])
    for path in (STRAIGHT, np.array([[0.0, 0.0], [0.5, 0.0], [0.8, 0.6]])):
        with_far = compute_velocity(ORIGIN, path, np.vstack([near, far]), P)
        assert with_far == compute_velocity(ORIGIN, path, near, P)
        assert compute_velocity(ORIGIN, path, far, P) == compute_velocity(ORIGIN, path, None, P)
