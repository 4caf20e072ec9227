import math

import numpy as np
import pytest

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import LETHAL, Costmap


def test_lethal_within_inscribed_radius_of_a_wall(room_costmap):
    # the west border wall's surface is at x = 0.1 m
    assert not room_costmap.is_free(0.1 + 0.1, 1.0)
    assert room_costmap.cost_at(0.1 + 0.1, 1.0) == LETHAL
    assert room_costmap.is_free(0.1 + 0.2, 1.0)


def test_cost_decays_with_distance_and_vanishes_beyond_inflation(room_costmap):
    xs = 0.1 + np.array([0.2, 0.3, 0.4, 0.5])
    costs = [room_costmap.cost_at(x, 1.0) for x in xs]
    assert all(0.0 < c < LETHAL for c in costs)
    assert costs == sorted(costs, reverse=True)
    assert room_costmap.cost_at(0.1 + 0.8, 1.0) == 0.0


def test_doorway_middle_is_cheaper_than_near_the_jamb(room_costmap):
    assert room_costmap.cost_at(3.05, 2.0) < room_costmap.cost_at(3.05, 1.75)


@pytest.mark.parametrize("xy", [(-1.0, 1.0), (1.0, -0.01), (6.5, 2.0), (1.0, 4.5)])
def test_outside_the_grid_is_lethal(room_costmap, xy):
    assert room_costmap.cost_at(*xy) == LETHAL
    assert not room_costmap.is_free(*xy)


def test_obstacle_points_are_inflated_without_touching_the_static_layer(room_costmap):
    cm = room_costmap.with_obstacles(np.array([[1.5, 2.0]]), 3.0)
    assert cm.obstacle_stamp == 3.0
    assert not cm.is_free(1.5 + 0.1, 2.0)
    assert 0.0 < cm.cost_at(1.5 + 0.3, 2.0) < LETHAL
    assert cm.cost_at(1.5 + 0.8, 2.0) == 0.0
    assert room_costmap.is_free(1.5 + 0.1, 2.0)  # the original is unchanged


def test_obstacle_layer_is_replaced_by_each_scan(room_costmap):
    first = room_costmap.with_obstacles(np.array([[1.5, 2.0]]), 1.0)
    second = first.with_obstacles(np.array([[4.5, 2.0]]), 1.1)
    assert second.is_free(1.5, 2.0)
    assert not second.is_free(4.5, 2.0)


def test_points_within_clear_radius_of_the_centre_are_ignored(room_costmap):
    pts = np.array([[1.5, 2.0], [4.5, 2.0]])
    cm = room_costmap.with_obstacles(pts, 0.0, clear_center=(1.4, 2.0), clear_radius=0.5)
    assert cm.is_free(1.5, 2.0)
    assert not cm.is_free(4.5, 2.0)


def test_points_on_static_walls_are_not_stamped_again(room_costmap):
    cm = room_costmap.with_obstacles(np.array([[0.05, 1.0], [3.05, 0.5]]), 0.0)
    assert len(cm.obstacle_points) == 0
    assert cm.cost is room_costmap.static_cost


def test_stamped_point_matches_static_inflation_of_one_cell():
    occ = np.zeros((41, 41), dtype=bool)
    occ[20, 20] = True
    static = Costmap(OccupancyGrid(occ, 0.05, 0.0, 0.0))
    empty = Costmap(OccupancyGrid(np.zeros_like(occ), 0.05, 0.0, 0.0))
    stamped = empty.with_obstacles(np.array([empty.cell_to_world(20, 20)]), 0.0)
    np.testing.assert_allclose(stamped.cost, static.cost, atol=1e-6)


def test_many_points_stay_cheap(room_costmap):
    # a 240-degree scan's worth of points: the stamp must not redo the EDT (behaviour check, not timing)
    rng = np.random.default_rng(1)
    pts = rng.uniform([0.5, 0.5], [5.5, 3.5], size=(500, 2))
    cm = room_costmap.with_obstacles(pts, 0.0)
    assert all(not cm.is_free(x, y) for x, y in pts[:20])


def test_inflation_radius_below_inscribed_is_rejected():
    with pytest.raises(ValueError):
        Costmap(OccupancyGrid(np.zeros((4, 4), bool), 0.05, 0.0, 0.0), inscribed_radius=0.3, inflation_radius=0.2)
    assert math.isinf(Costmap(OccupancyGrid(np.zeros((4, 4), bool), 0.05, 0.0, 0.0)).clearance_at(0.1, 0.1))


def test_a_blocked_path_check_answers_as_the_stamped_layer_without_stamping_the_map(room_costmap):
    # any_lethal on a fresh obstacle costmap used to copy and stamp the whole map for each scan
    rng = np.random.default_rng(5)
    for trial in range(40):
        points = rng.uniform((0.5, 0.5), (5.5, 3.5), size=(int(rng.integers(1, 30)), 2))
        xs, ys = rng.uniform(0.3, 5.7, 25), rng.uniform(0.3, 3.7, 25)
        lazy = room_costmap.with_obstacles(points, float(trial))
        answer = lazy.any_lethal(xs, ys)
        assert lazy._cost is None, "the check stamped the whole map"
        stamped = room_costmap.with_obstacles(points, float(trial))
        assert answer == bool((stamped.costs_at(np.stack([xs, ys], axis=1)) >= LETHAL).any())
        for x, y in zip(xs, ys):  # point by point too: the near/far edge of the lethal disc
            assert lazy.any_lethal(np.array([x]), np.array([y])) == (stamped.cost_at(x, y) >= LETHAL)


def test_a_window_of_costs_is_the_stamped_map_there_without_stamping_the_map(room_costmap):
    # a planner asks for its search window only; points near or beyond its edges are stamped too
    rng = np.random.default_rng(7)
    h, w = room_costmap.shape
    for trial in range(30):
        points = rng.uniform((0.2, 0.2), (5.8, 3.8), size=(int(rng.integers(1, 40)), 2))
        r0, c0 = int(rng.integers(-5, h - 5)), int(rng.integers(-5, w - 5))
        r1, c1 = r0 + int(rng.integers(1, 40)), c0 + int(rng.integers(1, 60))
        lazy = room_costmap.with_obstacles(points, float(trial))
        part = lazy.cost_in(r0, r1, c0, c1)
        assert lazy._cost is None, "the window stamped the whole map"
        full = room_costmap.with_obstacles(points, float(trial)).cost
        np.testing.assert_array_equal(part, full[max(r0, 0):r1, max(c0, 0):c1])
        # lookups inside the window read it; outside, the whole map is stamped, with the same costs
        rr = rng.integers(max(r0, 0), min(r1, h), 10)
        cc = rng.integers(max(c0, 0), min(c1, w), 10)
        xy = np.array([lazy.cell_to_world(r, c) for r, c in zip(rr, cc)])
        np.testing.assert_array_equal(lazy.costs_at(xy), full[rr, cc])
        assert [lazy.cost_at(x, y) for x, y in xy] == [float(v) for v in full[rr, cc]]
        assert lazy._cost is None
        np.testing.assert_array_equal(lazy.costs_at(np.array([[0.1, 0.1], [5.9, 3.9]])), full[[2, 78], [2, 118]])


def test_the_obstacle_layer_keeps_the_points_off_static_walls_outside_the_clear_radius(room_costmap):
    # with_obstacles runs on every scan: its shortcuts keep what the plain rules keep, in order
    rng = np.random.default_rng(11)
    for trial in range(30):
        pts = rng.uniform((-0.5, -0.5), (6.5, 4.5), size=(int(rng.integers(0, 300)), 2))
        centre, radius = tuple(rng.uniform((0.0, 0.0), (6.0, 4.0))), float(rng.choice([0.0, 0.5, 2.0]))
        cm = room_costmap.with_obstacles(pts, float(trial), clear_center=centre, clear_radius=radius)
        far = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1]) > radius if radius > 0.0 else np.ones(len(pts), bool)
        rows, cols, inside = room_costmap.cells_of(pts)
        keep = far & inside
        keep[keep] = room_costmap.static_clearance[rows[keep], cols[keep]] >= 1.5 * room_costmap.resolution
        np.testing.assert_array_equal(cm.obstacle_points, pts[keep])
        np.testing.assert_array_equal(cm.obstacle_cells, np.unique(rows[keep] * room_costmap.shape[1] + cols[keep]))
        assert (cm.cost is room_costmap.static_cost) == (not keep.any())


def test_stamped_costs_are_each_cells_highest_kernel_value(room_costmap):
    # the stamping against a plain loop over obstacle cells and kernel offsets, whole map and windows
    rng = np.random.default_rng(5)
    h, w = room_costmap.shape
    dr, dc, kval = room_costmap._kernel
    for trial in range(10):
        points = rng.uniform((0.0, 0.0), (6.0, 4.0), size=(int(rng.integers(1, 30)), 2))
        cm = room_costmap.with_obstacles(points, float(trial))
        want = room_costmap.static_cost.copy()
        for cell in cm.obstacle_cells:
            r, c = divmod(int(cell), w)
            for i in range(len(dr)):
                rr, cc = r + dr[i], c + dc[i]
                if 0 <= rr < h and 0 <= cc < w:
                    want[rr, cc] = max(want[rr, cc], kval[i])
        r0, c0 = int(rng.integers(-5, h - 5)), int(rng.integers(-5, w - 5))
        r1, c1 = r0 + int(rng.integers(1, 40)), c0 + int(rng.integers(1, 60))
        np.testing.assert_array_equal(cm.cost_in(r0, r1, c0, c1), want[max(r0, 0):r1, max(c0, 0):c1])
        np.testing.assert_array_equal(cm.cost, want)


def test_the_lethal_check_without_the_stamped_array_answers_as_the_stamped_array(room_costmap):
    # the compiled check reads the static layer and the scan obstacles' lethal discs; against the
    # stamped costs (`lethal`), point by point, with and without a clear radius
    rng = np.random.default_rng(9)
    for trial in range(40):
        points = rng.uniform((0.5, 0.5), (5.5, 3.5), size=(int(rng.integers(1, 30)), 2))
        xs, ys = rng.uniform(-0.2, 6.2, 25), rng.uniform(-0.2, 4.2, 25)
        lazy = room_costmap.with_obstacles(points, float(trial))
        stamped = room_costmap.with_obstacles(points, float(trial))
        _ = stamped.lethal  # builds the whole array: any_lethal then reads it
        for x, y in zip(xs, ys):
            want = not stamped.is_free(x, y)
            assert lazy.any_lethal(np.array([x]), np.array([y])) == want
            assert stamped.any_lethal(np.array([x]), np.array([y])) == want
            centre = (float(rng.uniform(0, 6)), float(rng.uniform(0, 4)))
            far = math.hypot(x - centre[0], y - centre[1]) > 0.5
            got = lazy.any_lethal(np.array([x]), np.array([y]), clear_center=centre, clear_radius=0.5)
            assert got == (want and far)


def test_a_costmap_built_from_one_with_scan_obstacles_checks_its_own_obstacles(room_costmap):
    # the lethal check's arguments are kept per costmap: one built by with_obstacles from a costmap
    # that has answered a check must not answer with its parent's obstacles
    rng = np.random.default_rng(12)
    g = room_costmap.grid
    free = np.argwhere(room_costmap.static_clearance > 0.5)
    for _ in range(20):
        a = np.array([g.cell_to_world(*free[i]) for i in rng.integers(0, len(free), 5)])
        b = np.array([g.cell_to_world(*free[i]) for i in rng.integers(0, len(free), 5)])
        first = room_costmap.with_obstacles(a, 0.0)
        assert first.any_lethal(a[:, 0], a[:, 1])
        second = first.with_obstacles(b, 1.0)
        fresh = room_costmap.with_obstacles(b, 1.0)
        for xs, ys in ((a[:, 0], a[:, 1]), (b[:, 0], b[:, 1])):
            for x, y in zip(xs, ys):
                assert second.any_lethal(np.array([x]), np.array([y])) == fresh.any_lethal(np.array([x]), np.array([y]))
