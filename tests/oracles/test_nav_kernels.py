"""The compiled navigation kernels (nav/kernels.py) make the decisions, and give the numbers, of the
numpy they replaced (oracles/nav.py), on random inputs and on scans and paths recorded from a
follow run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oracles import nav as ref
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.nav import kernels
from rescuemesh.nav.controller import ControllerParams, obstacle_reach
from rescuemesh.nav.costmap import Costmap

P = ControllerParams()


@pytest.fixture(scope="module")
def office_costmap():
    return Costmap(load_map(office_map_path()).grid)


def _lethal_args(cm):
    g = cm.grid
    lethal = cm._lethal if cm._lethal is not None else cm._static_lethal
    rc = cm._obstacle_rc if cm._lethal is None else (np.zeros(0, np.int64), np.zeros(0, np.int64))
    return (np.array([g.origin_x, g.origin_y]), cm.resolution, cm.shape, lethal, rc, cm._lethal_disc)


def _check_costmap(cm, points, clear_center, clear_radius, rng):
    h, w = cm.shape
    g = cm.grid
    cx, cy = clear_center if clear_center is not None else (0.0, 0.0)
    kept, cells, rows, cols = kernels.scan_obstacle_cells(np.ascontiguousarray(points), g.origin_x, g.origin_y,
                                                          cm.resolution, h, w, cm._stampable, cx, cy,
                                                          clear_radius if clear_center is not None else 0.0)
    want_kept, want_cells = ref.scan_obstacle_cells(points, np.array([g.origin_x, g.origin_y]), cm.resolution,
                                                    cm.shape, cm._stampable, clear_center, clear_radius)
    want_points = np.asarray(points, dtype=float).reshape(-1, 2)[want_kept]  # what costmap.py kept
    assert kept.tolist() == want_points.tolist() and cells.tolist() == want_cells.tolist()
    want_rows, want_cols = np.divmod(want_cells, w)  # what costmap.py computed from the cells
    assert rows.tolist() == want_rows.tolist() and cols.tolist() == want_cols.tolist()
    with_scan = cm.with_obstacles(points, 0.0, clear_center=clear_center, clear_radius=clear_radius)
    args = _lethal_args(with_scan)
    for _ in range(20):  # path samples: short runs of points near the scan
        start = points[rng.integers(len(points))] if len(points) else rng.uniform(0, 10, 2)
        samples = start + np.cumsum(rng.normal(0, 0.05, (int(rng.integers(1, 40)), 2)), axis=0)
        xs, ys = np.ascontiguousarray(samples[:, 0]), np.ascontiguousarray(samples[:, 1])
        centre, radius = tuple(samples[-1] + rng.normal(0, 0.3, 2)), float(rng.choice([0.0, 0.3, 0.6]))
        assert with_scan.any_lethal(xs, ys) == ref.any_lethal(xs, ys, *args)
        assert with_scan.any_lethal(xs, ys, clear_center=centre, clear_radius=radius) == \
            ref.blocked(xs, ys, centre, radius, *args)


def test_scan_obstacles_and_the_lethal_check_are_the_oracles_on_random_inputs(office_costmap):
    rng = np.random.default_rng(21)
    cm = office_costmap
    g = cm.grid
    size = np.array([cm.shape[1], cm.shape[0]]) * cm.resolution
    for trial in range(60):
        n = int(rng.integers(0, 400))
        points = np.array([g.origin_x, g.origin_y]) + rng.uniform(-0.5, 1.05, (n, 2)) * size
        if n and trial % 5 == 0:
            points[rng.integers(n)] = (np.nan, np.inf)  # a no-return, off the grid
        centre = tuple(points[0]) if n and trial % 2 else None
        _check_costmap(cm, points, centre, float(rng.choice([0.0, 0.4, 1.0])), rng)


def _check_clearance(points, x0, y0, yaw, curvature, horizon):
    got = kernels.scan_clearance(np.ascontiguousarray(points), x0, y0, yaw, obstacle_reach(P), curvature,
                                 P.footprint_radius, P.corridor_margin, horizon)
    x, y = ref.robot_frame_xy(x0, y0, yaw, points, obstacle_reach(P))
    want = ref.clearance(x, y, curvature, P.footprint_radius, P.corridor_margin, horizon)
    assert got == pytest.approx(want, rel=1e-12, abs=1e-12) or (math.isinf(got) and math.isinf(want))
    return got


def test_the_swept_footprint_clearance_is_the_oracles_on_random_inputs():
    rng = np.random.default_rng(22)
    finite = 0
    for trial in range(400):
        x0, y0, yaw = *rng.uniform(-3, 3, 2), float(rng.uniform(-math.pi, math.pi))
        points = np.array([x0, y0]) + rng.normal(0, 1.0, (int(rng.integers(0, 300)), 2))
        curvature = float(rng.choice([0.0, 5e-4, -5e-4, *rng.uniform(-4, 4, 5)]))
        horizon = float(rng.choice([math.inf, 0.5, 2.0]))
        finite += math.isfinite(_check_clearance(points, x0, y0, yaw, curvature, horizon))
    assert finite > 100  # the corridor was not always empty


def test_the_kernels_are_the_oracles_on_scans_and_paths_recorded_from_a_follow_run(office_costmap, monkeypatch):
    from rescuemesh.nav import controller, navigate
    from rescuemesh.scenarios import ScenarioOptions
    from rescuemesh.scenarios.runner import run_scenario

    recorded = {"scans": [], "velocity": []}
    compute = controller.command_on_part
    with_obstacles = Costmap.with_obstacles

    def record_scan(self, points, now, **kw):
        if len(recorded["scans"]) < 60:
            recorded["scans"].append((np.array(points, dtype=float), kw.get("clear_center"), kw.get("clear_radius", 0)))
        return with_obstacles(self, points, now, **kw)

    def record_velocity(pose, points, cum, s_start, s_end, scan_points, params, current_speed):
        if scan_points is not None and len(scan_points) and len(recorded["velocity"]) < 200:
            recorded["velocity"].append((pose, np.array(scan_points, dtype=float)))
        return compute(pose, points, cum, s_start, s_end, scan_points, params, current_speed)

    monkeypatch.setattr(Costmap, "with_obstacles", record_scan)
    monkeypatch.setattr(navigate, "command_on_part", record_velocity)
    run_scenario("follow", ScenarioOptions(seed=0))
    assert len(recorded["scans"]) == 60 and len(recorded["velocity"]) == 200
    rng = np.random.default_rng(23)
    for points, centre, radius in recorded["scans"]:
        _check_costmap(office_costmap, points, centre, radius, rng)
    for pose, points in recorded["velocity"]:
        for curvature in (0.0, 0.8, -1.5):
            _check_clearance(points, pose.x, pose.y, pose.yaw, curvature, math.inf)
