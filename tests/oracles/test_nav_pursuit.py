"""The compiled controller (nav/pursuit_kernels.py) against the Python it replaced (tests/oracles/nav.py):
the same numbers, bit for bit, on random and recorded inputs."""

import math
import types

import numpy as np
import pytest

import oracles.nav as ref
from rescuemesh.geometry import Pose2D
from rescuemesh.nav import ControllerParams, compute_velocity
from rescuemesh.nav.controller import command_on_part
from rescuemesh.nav.path import Path, Polyline
from rescuemesh.nav.pursuit_kernels import project

P = ControllerParams()


def _random_path(rng):
    n = int(rng.choice([1, 2, 3, 8, 30]))
    pts = np.cumsum(rng.normal(0.0, rng.choice([0.05, 0.4, 1.5]), (n, 2)), axis=0)
    if n > 2 and rng.random() < 0.3:
        pts[int(rng.integers(1, n))] = pts[int(rng.integers(0, n - 1))]  # a repeated vertex: a zero-length segment
    return Path.from_points(pts)


def _outcome(call, *args, **kw):
    """call(*args, **kw), or the type of the error it raised (both sides must raise the same)."""
    try:
        return call(*args, **kw)
    except ArithmeticError as e:
        return type(e)


def _check_part(pose, path, s_start, s_end, scan, speed):
    got = _outcome(command_on_part, pose, path.points, path.cum, s_start, s_end, scan, P, speed)
    want = _outcome(ref.polyline_slice_command, pose, path.points, path.cum, s_start, s_end, scan, P, speed)
    assert got == want, (got, want)
    return got


def _check_project(path, x, y, s_min, s_max):
    got = _outcome(project, path.points, path.cum, x, y, s_min, s_max)
    want = _outcome(ref.Polyline.from_points(path.points, cum=path.cum).project, x, y, s_min=s_min, s_max=s_max)
    assert got == (want if isinstance(want, type) else want[0]), (got, want)
    return got


def test_the_controller_is_the_oracle_on_random_paths_poses_and_scans():
    rng = np.random.default_rng(41)
    moving = raised = 0
    for trial in range(3000):
        path = _random_path(rng)
        length = path.length_m
        anchor = path.points[int(rng.integers(0, len(path.points)))]
        x, y = anchor + rng.normal(0.0, rng.choice([0.05, 0.5, 2.0]), 2)
        pose = Pose2D(float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
        s_start = float(rng.choice([0.0, -0.5, length, length + 1.0, *rng.uniform(0.0, length + 1e-9, 3)]))
        s_end = float(rng.choice([length, length + 0.3, s_start, s_start + 1e-10, *rng.uniform(-0.2, length + 0.5, 2)]))
        scan = None
        if trial % 3:
            scan = np.array([x, y]) + rng.normal(0.0, rng.choice([0.3, 1.0]), (int(rng.integers(0, 200)), 2))
        speed = float(rng.choice([0.0, 0.2, 0.5, -0.3]))
        v, _ = _check_part(pose, path, s_start, s_end, scan, speed)
        moving += v > 0.0
        for _ in range(3):
            s_min = float(rng.uniform(-0.5, length + 0.5))
            # s_max below s_min (no caller's): a zero-length segment then divides by zero, on both sides
            raised += _check_project(path, float(x), float(y), s_min,
                                     float(rng.choice([s_min + 2.0, s_min - 0.1, math.inf]))) is ZeroDivisionError
    assert moving > 300 and raised  # not only rotations in place and stops


def test_compute_velocity_is_the_oracle_with_goal_yaw_and_tolerance():
    rng = np.random.default_rng(42)
    for trial in range(1500):
        path = _random_path(rng)
        x, y = path.points[-1] + rng.normal(0.0, 0.3, 2)
        pose = Pose2D(float(x), float(y), float(rng.uniform(-4.0, 4.0)))
        goal_yaw = None if trial % 3 == 0 else float(rng.uniform(-7.0, 7.0))
        line = path.points if trial % 2 else Polyline.from_points(path.points)
        kw = dict(goal_yaw=goal_yaw, xy_tolerance=float(rng.choice([0.0, 0.15, 0.5])),
                  current_speed=None if trial % 5 == 0 else float(rng.uniform(-0.5, 0.5)))
        scan = np.array([x, y]) + rng.normal(0.0, 1.0, (50, 2)) if trial % 4 else None
        assert compute_velocity(pose, line, scan, P, **kw) == ref.compute_velocity(pose, line, scan, P, **kw)


def test_the_controller_is_the_oracle_on_ticks_recorded_from_a_follow_run(monkeypatch):
    from rescuemesh.nav import navigate
    from rescuemesh.scenarios import ScenarioOptions
    from rescuemesh.scenarios.runner import run_scenario

    ticks, projections = [], []
    part, proj = navigate.command_on_part, navigate.pursuit_kernels.project

    def record_part(*args):
        if len(ticks) < 600:
            pose, points, cum, s0, s1, scan, params, speed = args
            ticks.append((pose, points.copy(), cum.copy(), s0, s1, np.array(scan), params, speed))
        return part(*args)

    def record_project(points, cum, x, y, s_min, s_max):
        if len(projections) < 600:
            projections.append((points.copy(), cum.copy(), x, y, s_min, s_max))
        return proj(points, cum, x, y, s_min, s_max)

    monkeypatch.setattr(navigate, "command_on_part", record_part)
    monkeypatch.setattr(navigate, "pursuit_kernels", types.SimpleNamespace(project=record_project))
    run_scenario("follow", ScenarioOptions(seed=0))
    assert len(ticks) == 600 and len(projections) == 600
    moving = 0
    for pose, points, cum, s0, s1, scan, params, speed in ticks:
        got = part(pose, points, cum, s0, s1, scan, params, speed)
        assert got == ref.polyline_slice_command(pose, points, cum, s0, s1, scan, params, speed)
        moving += got[0] > 0.0
    assert moving > 300
    for points, cum, x, y, s_min, s_max in projections:
        want, _ = ref.Polyline.from_points(points, cum=cum).project(x, y, s_min=s_min, s_max=s_max)
        assert proj(points, cum, x, y, s_min, s_max) == want


def test_the_package_polyline_is_the_python_one_it_replaced():
    # Polyline.point_at, .project and .slice used to be Python beside the compiled kernels (two
    # implementations of one geometry); they now call the kernels and must answer as the Python did
    rng = np.random.default_rng(44)
    for _ in range(1500):
        path = _random_path(rng)
        got_line, want_line = Polyline.from_points(path.points, cum=path.cum), ref.Polyline.from_points(path.points,
                                                                                                      cum=path.cum)
        length = path.length_m
        x, y = (float(v) for v in path.points[0] + rng.normal(0.0, 1.0, 2))
        for s in (-0.5, 0.0, length, length + 1.0, *rng.uniform(0.0, length + 1e-9, 3).tolist()):
            assert got_line.point_at(s) == want_line.point_at(s), s
        s_min = float(rng.uniform(-0.5, length + 0.5))
        for s_max in (s_min + 2.0, math.inf):
            assert _outcome(got_line.project, x, y, s_min=s_min, s_max=s_max) == \
                _outcome(want_line.project, x, y, s_min=s_min, s_max=s_max)
        s0 = float(rng.choice([0.0, -0.5, length, *rng.uniform(0.0, length, 2)]))
        for s1 in (length, s0, s0 + 1e-10, float(rng.uniform(-0.2, length + 0.5))):
            got, want = got_line.slice(s0, s1), want_line.slice(s0, s1)
            assert (got.xs, got.ys, got.cum, got.length) == (want.xs, want.ys, want.cum, want.length), (s0, s1)
    with pytest.raises(ValueError, match="empty Polyline"):
        Polyline([], [], []).point_at(0.0)
