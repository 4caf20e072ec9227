"""The compiled blocked-path samples, scan points, planner coarse grid and shortcutting
(nav/kernels.py, body_kernels.py) give the numbers and decisions of the numpy they replaced
(oracles/nav.py), on random inputs and on inputs recorded from a follow run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oracles import nav as ref
from rescuemesh.body import LaserScan, _beam_angles
from rescuemesh.body_kernels import scan_points
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.nav import kernels
from rescuemesh.nav.costmap import Costmap
from rescuemesh.nav.path import cumulative_lengths
from rescuemesh.nav.planner import MCPPlanner, shortcut


@pytest.fixture(scope="module")
def office_costmap():
    return Costmap(load_map(office_map_path()).grid)


# -- the blocked-path check ---------------------------------------------------------------------------


def test_arange_and_interp_are_numpys_on_random_inputs():
    rng = np.random.default_rng(31)
    for _ in range(3000):
        start = float(rng.uniform(-5, 5))
        stop = start + float(rng.uniform(-1, 20))
        step = float(rng.choice([0.05, 0.025, 0.1, rng.uniform(1e-3, 1.0)]))
        np.testing.assert_array_equal(kernels.arange(start, stop, step), np.arange(start, stop, step))
    for _ in range(2000):
        n = int(rng.integers(1, 9))
        xp = np.cumsum(rng.choice([0.0, 0.3, 1.0, float(rng.uniform(0, 2))], n))  # repeated vertices too
        fp = rng.uniform(-5, 5, n)
        x = np.concatenate([rng.uniform(-1, xp[-1] + 1, 40), xp, [np.nan]])
        np.testing.assert_array_equal(kernels.interp(x, xp, fp), np.interp(x, xp, fp))


def _extent(cm):
    """(lower-left corner, width and height) of costmap `cm`'s map, in m."""
    return np.array([cm.grid.origin_x, cm.grid.origin_y]), np.array(cm.shape[::-1]) * cm.resolution


def _check_path(cm, points, s0, centre, radius):
    points = np.ascontiguousarray(points, dtype=float)
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))))
    xs, ys = ref.path_samples(points, cum, s0, cum[-1], cm.resolution)
    want = cm.any_lethal(xs, ys, clear_center=centre, clear_radius=radius)  # the compiled check of points
    got = cm.any_lethal_along(points, cum, s0, cum[-1], cm.resolution, clear_center=centre, clear_radius=radius)
    assert got == want
    return got


def test_the_path_check_is_sampling_then_the_lethal_check_on_random_paths(office_costmap):
    rng = np.random.default_rng(32)
    lo, size = _extent(office_costmap)
    scan = lo + rng.uniform(0, 1, (300, 2)) * size
    blocked = 0
    for trial in range(300):
        cm = office_costmap if trial % 2 else office_costmap.with_obstacles(scan, 0.0)
        n = int(rng.integers(1, 12))
        points = lo + rng.uniform(0.1, 0.9, 2) * size + np.cumsum(rng.normal(0, 0.6, (n, 2)), axis=0)
        if n > 2 and trial % 3 == 0:
            points[1] = points[2]  # a zero-length segment
        centre = tuple(points[-1]) if trial % 4 else None
        blocked += _check_path(cm, points, float(rng.uniform(0, 0.5)), centre, float(rng.choice([0.0, 0.5])))
    assert 30 < blocked < 270  # both answers were checked


def _check_segment(cm, a, b, samples):
    xs, ys = ref.segment_samples_between(a, b, samples)
    got = cm.segment_any_lethal(a, b, samples)
    assert got == cm.any_lethal(xs, ys)
    return got


def test_the_straight_extension_check_is_linspace_then_the_lethal_check(office_costmap):
    rng = np.random.default_rng(38)
    lo, size = _extent(office_costmap)
    cm = office_costmap.with_obstacles(lo + rng.uniform(0, 1, (200, 2)) * size, 0.0)
    blocked = 0
    for trial in range(400):
        a = tuple(lo + rng.uniform(0.05, 0.95, 2) * size)
        b = tuple(np.array(a) + rng.normal(0, 0.7, 2))
        samples = max(2, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / (0.5 * cm.resolution)) + 1)
        blocked += _check_segment(cm if trial % 2 else office_costmap, a, b, int(samples))
    assert 40 < blocked < 360
    # ends a hair inside a wall's lethal cells, the way there free: only the last sample, exactly at
    # the end, is lethal
    lethal = office_costmap.lethal
    rows, cols = np.nonzero(lethal[:, 11:] & ~lethal[:, 10:-1])
    walls = 0
    for r, c in zip(rows[::7], cols[::7] + 11):
        if lethal[r, c - 11 : c].any():
            continue
        y = lo[1] + (r + 0.5) * office_costmap.resolution
        edge = lo[0] + c * office_costmap.resolution
        a, b = (edge - 0.45, y), (edge + 1e-9, y)
        assert office_costmap.world_to_cell(*b) == (r, c)
        samples = math.ceil(0.45 / (0.5 * office_costmap.resolution)) + 1
        assert _check_segment(office_costmap, a, b, samples)
        walls += 1
    assert walls > 20


def test_arc_lengths_are_the_oracles():
    rng = np.random.default_rng(39)
    for n in (0, 1, 2, 3, 10, 50):
        for _ in range(30):
            points = np.cumsum(rng.normal(0, 1, (n, 2)), axis=0)
            if n > 2:
                points[1] = points[2]
            np.testing.assert_array_equal(cumulative_lengths(points), ref.cumulative_lengths(points))
            np.testing.assert_array_equal(cumulative_lengths(points.T.copy().T), ref.cumulative_lengths(points))


# -- scan points ------------------------------------------------------------------------------------


def _check_scan(scan: LaserScan):
    angles = _beam_angles(scan.angle_min, scan.angle_increment, len(scan.ranges))
    want = ref.points_in_map(scan.ranges, angles, scan.range_min, scan.range_max,
                              scan.origin.x, scan.origin.y, scan.origin.yaw)
    got = scan.points_in_map()
    np.testing.assert_array_equal(got, want)
    assert got.flags.c_contiguous


def test_scan_points_are_the_oracles_on_random_sweeps():
    rng = np.random.default_rng(33)
    for trial in range(200):
        n = int(rng.choice([0, 1, 90, 683]))
        ranges = rng.uniform(0.0, 7.0, n)
        ranges[rng.random(n) < 0.2] = np.inf
        ranges[rng.random(n) < 0.05] = np.nan
        ranges[rng.random(n) < 0.05] = 0.02  # exactly range_min
        fov = math.radians(240.0 if trial % 2 else 360.0)
        scan = LaserScan(float(trial), Pose2D(*rng.uniform(-5.0, 5.0, 2), rng.uniform(-math.pi, math.pi)),
                         -0.5 * fov, fov / max(n - 1, 1), 0.02, float(rng.choice([5.6, 7.0, math.inf])), ranges)
        _check_scan(scan)
    assert scan_points(np.zeros(0), np.zeros(0), 0.0, 1.0, 0.0, 0.0, 0.0).shape == (0, 2)


# -- the planner's coarse grid ------------------------------------------------------------------------


def _check_coarse(cost, k, window, weight=8.0):
    r0, r1, c0, c1 = window
    rows, cols = (r1 - r0, c1 - c0) if k > 1 else cost.shape
    # into a larger Fortran-ordered array holding an older graph's costs, as a planner's graph may
    step = np.asfortranarray(np.random.default_rng(rows * cols).uniform(0.0, 9.0, (rows + 5, cols + 16)))
    lethal = kernels.coarse_step_costs(cost, k, rows, cols, np.float32(weight), step)
    want_lethal, want_step = ref.graph_costs(cost, k, window, weight)
    assert want_step.dtype == np.float32  # numpy's arithmetic was float32: the kernel's too
    np.testing.assert_array_equal(lethal, want_lethal)
    np.testing.assert_array_equal(step[:rows, :cols], want_step.astype(np.float64))  # what MCP_Geometric reads
    assert np.isinf(step[rows:]).all() and np.isinf(step[:, cols:]).all()  # beyond the window: impassable


def test_the_coarse_grid_is_the_oracles_on_random_windows(office_costmap):
    rng = np.random.default_rng(34)
    cm = office_costmap.with_obstacles(
        np.array([office_costmap.grid.origin_x, office_costmap.grid.origin_y])
        + rng.uniform(0, 1, (200, 2)) * np.array(office_costmap.shape[::-1]) * office_costmap.resolution, 0.0)
    h, w = cm.shape
    for trial in range(150):
        k = int(rng.choice([1, 2, 3]))
        rows, cols = -(-h // k), -(-w // k)
        r0, c0 = int(rng.integers(0, rows)), int(rng.integers(0, cols))
        r1, c1 = int(rng.integers(r0 + 1, rows + 1)), int(rng.integers(c0 + 1, cols + 1))
        if trial % 5 == 0:
            r0, r1, c0, c1 = 0, rows, 0, cols  # the whole map: blocks past its edge
        _check_coarse(cm.cost_in(r0 * k, r1 * k, c0 * k, c1 * k), k, (r0, r1, c0, c1))
    random_costs = rng.uniform(0, 1.2, (37, 41)).clip(0, 1).astype(np.float32)
    _check_coarse(random_costs, 2, (0, 19, 0, 21))
    _check_coarse(random_costs[3:30, 5:40], 2, (0, 14, 0, 18))  # a view, as cost_in may give


# -- stamping scan obstacles --------------------------------------------------------------------------


def _check_stamped(cm, rng, windows=20):
    h, w = cm.shape
    for _ in range(windows):
        r0, c0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        r1, c1 = int(rng.integers(r0 + 1, h + 1)), int(rng.integers(c0 + 1, w + 1))
        got = cm._stamped(r0, r1, c0, c1)
        want = ref.stamped(cm.static_cost, r0, r1, c0, c1, cm._obstacle_rc, cm._kernel, cm._kernel_reach)
        assert got.dtype == want.dtype and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(cm._stamped(0, h, 0, w), ref.stamped(cm.static_cost, 0, h, 0, w, cm._obstacle_rc,
                                                                     cm._kernel, cm._kernel_reach))


def test_stamping_is_the_oracles_on_random_obstacles_and_windows(office_costmap):
    rng = np.random.default_rng(36)
    g = office_costmap.grid
    size = np.array(office_costmap.shape[::-1]) * office_costmap.resolution
    for trial in range(20):
        points = np.array([g.origin_x, g.origin_y]) + rng.uniform(-0.1, 1.1, (int(rng.integers(0, 300)), 2)) * size
        _check_stamped(office_costmap.with_obstacles(points, 0.0), rng)


# -- shortcutting ------------------------------------------------------------------------------------


def _cell_path(cm, rng, n):
    """A random 8-connected walk of cell centres (m) from a random cell of the map."""
    h, w = cm.shape
    rc = np.array([rng.integers(0, h), rng.integers(0, w)])
    steps = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)])
    rcs = rc + np.cumsum(np.vstack([[0, 0], steps[rng.integers(0, 8, n - 1)] * rng.integers(1, 3)]), axis=0)
    g = cm.grid
    return np.column_stack([g.origin_x + (rcs[:, 1] + 0.5) * cm.resolution,
                            g.origin_y + (rcs[:, 0] + 0.5) * cm.resolution])


def _check_shortcut(cm, points):
    got = shortcut(cm, points)
    want = ref.shortcut(cm, points)
    np.testing.assert_array_equal(got, want)
    return len(got)


def test_shortcutting_is_the_oracles_on_random_cell_paths(office_costmap):
    rng = np.random.default_rng(35)
    g = office_costmap.grid
    size = np.array(office_costmap.shape[::-1]) * office_costmap.resolution
    shortened = 0
    for trial in range(200):
        cm = office_costmap
        if trial % 2:
            cm = office_costmap.with_obstacles(np.array([g.origin_x, g.origin_y]) + rng.uniform(0, 1, (150, 2)) * size,
                                               0.0)
            h, w = cm.shape
            r0, c0 = int(rng.integers(0, h - 20)), int(rng.integers(0, w - 20))
            cm.cost_in(r0, r0 + int(rng.integers(5, 80)), c0, c0 + int(rng.integers(5, 80)))  # a stamped window
        n = int(rng.integers(1, 60))
        points = _cell_path(cm, rng, n)
        shortened += _check_shortcut(cm, points) < n
    assert shortened > 50


# -- recorded from a follow run ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def recorded():
    from rescuemesh.nav import navigate, planner
    from rescuemesh.scenarios import ScenarioOptions
    from rescuemesh.scenarios.runner import run_scenario

    rec = {"scans": [], "paths": [], "shortcuts": [], "coarse": [], "segments": [], "polylines": []}
    points_in_map = LaserScan.points_in_map
    any_lethal_along = Costmap.any_lethal_along
    graph_over = MCPPlanner._graph_over
    short = planner.shortcut
    segment_any_lethal = Costmap.segment_any_lethal
    from_points = navigate.Path.from_points.__func__

    def record_segment(self, a, b, samples):
        if len(rec["segments"]) < 300:
            rec["segments"].append((self, a, b, samples))
        return segment_any_lethal(self, a, b, samples)

    def record_polyline(cls, points):
        if len(rec["polylines"]) < 300:
            rec["polylines"].append(np.array(points, dtype=float))
        return from_points(cls, points)

    def record_scan(self):
        if len(rec["scans"]) < 100:
            rec["scans"].append(self)
        return points_in_map(self)

    def record_path(self, points, cum, s0, s1, step, **kw):
        if len(rec["paths"]) < 300:
            rec["paths"].append((self, np.array(points), float(s0), kw["clear_center"], kw["clear_radius"]))
        return any_lethal_along(self, points, cum, s0, s1, step, **kw)

    def record_coarse(self, cost, window, *graph):
        if len(rec["coarse"]) < 60:
            rec["coarse"].append((cost.copy(), self.downsample, window))
        return graph_over(self, cost, window, *graph)

    def record_shortcut(costmap, points, **kw):
        if len(rec["shortcuts"]) < 200:
            rec["shortcuts"].append((costmap, np.array(points)))
        return short(costmap, points, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(LaserScan, "points_in_map", record_scan)
        mp.setattr(Costmap, "any_lethal_along", record_path)
        mp.setattr(MCPPlanner, "_graph_over", record_coarse)
        mp.setattr(planner, "shortcut", record_shortcut)
        mp.setattr(Costmap, "segment_any_lethal", record_segment)
        mp.setattr(navigate.Path, "from_points", classmethod(record_polyline))
        run_scenario("follow", ScenarioOptions(seed=0))
    assert navigate.NavigateToPose._blocked  # (the path check is what _blocked calls)
    return rec


def test_the_kernels_are_the_oracles_on_inputs_recorded_from_a_follow_run(recorded, office_costmap):
    assert len(recorded["scans"]) == 100 and len(recorded["coarse"]) >= 20
    assert len(recorded["paths"]) >= 100 and len(recorded["shortcuts"]) >= 20
    rng = np.random.default_rng(37)
    for scan in recorded["scans"]:
        _check_scan(scan)
    for scan in recorded["scans"][::10]:
        _check_stamped(office_costmap.with_obstacles(scan.points_in_map(), 0.0), rng, 5)
    for cm, points, s0, centre, radius in recorded["paths"]:
        _check_path(cm, points, s0, centre, radius)
    for cost, k, window in recorded["coarse"]:
        _check_coarse(cost, k, window)
    for cm, points in recorded["shortcuts"]:
        _check_shortcut(cm, points)
    assert len(recorded["segments"]) >= 50 and len(recorded["polylines"]) >= 30  # one a plan (extensions: extended_to)
    for cm, a, b, samples in recorded["segments"]:
        _check_segment(cm, a, b, samples)
    for points in recorded["polylines"]:
        np.testing.assert_array_equal(cumulative_lengths(points), ref.cumulative_lengths(points))


# -- the bound on paths leaving a search window ------------------------------------------------------


def test_the_exit_bound_is_the_oracles_on_random_windows_costs_and_fields():
    from rescuemesh.nav.planner import _exit_bound

    rng = np.random.default_rng(38)
    whole = (0, 60, 0, 90)
    finite = 0
    for trial in range(400):
        r0, c0 = int(rng.integers(0, 50)), int(rng.integers(0, 80))
        r1, c1 = int(rng.integers(r0 + 1, 61)), int(rng.integers(c0 + 1, 91))
        window = (r0, r1, c0, c1)
        cum = rng.uniform(0.0, 80.0, (r1 - r0, c1 - c0))
        cum[rng.random(cum.shape) < 0.3] = np.inf
        if trial % 3 == 0:  # as the search returns it: a Fortran-ordered array's corner
            big = np.asfortranarray(np.full((r1 - r0 + 7, c1 - c0 + 9), -1.0))
            big[: r1 - r0, : c1 - c0] = cum
            cum = big[: r1 - r0, : c1 - c0]
        goal = (int(rng.integers(0, r1 - r0)), int(rng.integers(0, c1 - c0)))
        field = None
        if trial % 2:
            field = rng.uniform(0.0, 50.0, (60, 90))
            field[rng.random(field.shape) < 0.2] = np.inf
        got, want = _exit_bound(cum, window, goal, whole, field), ref.exit_bound(cum, window, goal, whole, field)
        assert got == want, trial
        finite += math.isfinite(want)
    assert finite > 200


def test_a_path_extended_by_a_waypoint_is_the_path_of_all_its_points():
    # a follower's path grows by its leader's new pose: the same points, arc lengths and length as
    # Path.from_points(np.vstack(...)), what NavigateToPose._extended built before
    from rescuemesh.nav.path import Path

    rng = np.random.default_rng(39)
    for trial in range(500):
        points = np.cumsum(rng.normal(0.0, float(rng.choice([0.01, 0.3, 3.0])), (int(rng.integers(1, 40)), 2)), axis=0)
        x, y = points[-1] + rng.normal(0.0, 0.5, 2) if trial % 7 else points[-1]
        got = Path.from_points(points).extended_to(float(x), float(y))
        want = Path.from_points(np.vstack([points, [[x, y]]]))
        np.testing.assert_array_equal(got.points, want.points)
        np.testing.assert_array_equal(got.cum, want.cum)
        assert got.length_m == want.length_m and got.points.flags.c_contiguous
