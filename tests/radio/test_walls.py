"""radio/walls.py: walls crossed on a straight segment of the occupancy grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rescuemesh.maps import OccupancyGrid, load_map, office_map_path
from rescuemesh.radio.walls import count_walls, count_walls_cells, count_walls_many


@pytest.fixture(scope="module")
def grid() -> OccupancyGrid:
    """4 m x 2 m at 0.1 m: a one-cell wall at x 1.0..1.1, a two-cell wall at x 2.0..2.2 with a
    gap at y 1.5..2.0, and a block at x 3.0..3.3, y 0.0..0.3."""
    occ = np.zeros((20, 40), dtype=bool)
    occ[:, 10] = True
    occ[:15, 20:22] = True
    occ[0:3, 30:33] = True
    return OccupancyGrid(occupied=occ, resolution=0.1, origin_x=0.0, origin_y=0.0)


@pytest.mark.parametrize(("a", "b", "walls"), [
    ((0.2, 0.5), (0.8, 1.5), 0),  # free space
    ((0.5, 1.0), (1.5, 1.0), 1),  # the thin wall
    ((0.5, 1.0), (2.5, 1.0), 2),  # thin and thick
    ((1.5, 0.5), (2.5, 0.5), 1),  # the 2-cell wall counts once
    ((1.5, 1.7), (2.5, 1.7), 0),  # through the gap
    ((0.5, 0.2), (2.9, 1.8), 2),  # diagonal: thin wall, then thick wall below the gap
    ((0.5, 0.05), (3.9, 1.95), 2),  # diagonal: thin wall, thick wall, then above the block
    ((1.05, 1.0), (1.5, 1.0), 0),  # starts inside a wall: that wall does not count
    ((1.05, 1.0), (2.5, 1.0), 1),  # ... the next one does
    ((0.5, 1.0), (1.05, 1.0), 1),  # ends inside a wall: it was entered
    ((3.5, 0.1), (3.5, 1.0), 0),
    ((2.5, 0.15), (3.9, 0.15), 1),  # the block
])
def test_hand_made_segments(grid, a, b, walls):
    assert count_walls(grid, a, b) == walls
    assert count_walls_many(grid, a, np.array([b]))[0] == walls


def test_diagonal_through_the_gap_and_over_the_block(grid):
    # through the thin wall, rising through the gap of the thick wall (y 1.63 at x 2.0)
    assert count_walls(grid, (0.5, 1.4), (3.8, 1.9)) == 1
    # a little lower, the same slope meets the thick wall below its gap (y 1.41 at x 2.0)
    assert count_walls(grid, (0.5, 1.0), (3.8, 1.9)) == 2


def test_off_grid_counts_as_occupied(grid):
    assert count_walls(grid, (0.5, 1.0), (0.5, 2.5)) == 1  # ends outside
    assert count_walls(grid, (3.5, 1.9), (3.9, 2.3)) == 1
    assert count_walls(grid, (-1.0, 1.0), (0.5, 1.0)) == 0  # starts outside: not counted


def test_zero_length_segment(grid):
    assert count_walls(grid, (0.5, 0.5), (0.5, 0.5)) == 0
    assert count_walls(grid, (1.05, 0.5), (1.05, 0.5)) == 0


def test_vectorised_equals_scalar_on_random_segments():
    office = load_map(office_map_path()).grid
    rng = np.random.default_rng(7)
    a = (3.0, 4.6)
    pts = rng.uniform((-0.5, -0.5), (20.0, 9.7), size=(600, 2))
    many = count_walls_many(office, a, pts)
    assert many.tolist() == [count_walls(office, a, tuple(p)) for p in pts]
    assert many.max() >= 3 and many.min() == 0
    for _ in range(30):  # other transmitters too
        tx = tuple(rng.uniform((0, 0), (19.5, 9.2)))
        pts = rng.uniform((0, 0), (19.5, 9.2), size=(20, 2))
        assert count_walls_many(office, tx, pts).tolist() == [count_walls(office, tx, tuple(p)) for p in pts]


def test_vectorised_handles_empty_input(grid):
    assert count_walls_many(grid, (0.5, 0.5), np.zeros((0, 2))).shape == (0,)


def test_office_walls():
    office = load_map(office_map_path()).grid
    assert count_walls(office, (5.0, 8.0), (15.0, 8.0)) == 2  # hall east wall, wall at x 13.6
    assert count_walls(office, (3.0, 4.6), (15.0, 4.6)) == 0  # through the passage and the doorway


def test_cell_count_equals_the_count_between_the_cell_centres():
    """BleChannel counts walls from its cells: the same as count_walls between their centres,
    on and off the grid (the office's grid; cells are (row, col))."""
    office = load_map(office_map_path()).grid
    q, ox, oy = float(office.resolution), float(office.origin_x), float(office.origin_y)
    n_rows, n_cols = office.occupied.shape
    rng = np.random.default_rng(11)
    cells = rng.integers((-5, -5, -5, -5), (n_rows + 5, n_cols + 5, n_rows + 5, n_cols + 5), size=(400, 4))
    counts = []
    for r0, c0, r1, c1 in cells.tolist():
        centre = lambda r, c: (ox + (c + 0.5) * q, oy + (r + 0.5) * q)  # noqa: E731 (as BleChannel._centre)
        counts.append(count_walls_cells(office, r0, c0, r1, c1))
        assert counts[-1] == count_walls(office, centre(r0, c0), centre(r1, c1))
    assert max(counts) >= 3 and min(counts) == 0


def test_each_wall_is_priced_by_the_material_where_the_path_enters_it():
    from rescuemesh.radio.walls import wall_loss_cells, wall_loss_many

    occ = np.zeros((10, 60), dtype=bool)
    codes = np.zeros((10, 60), dtype=np.uint8)
    occ[:, 10:12], codes[:, 10:12] = True, 3  # concrete
    occ[:, 30:32], codes[:, 30:32] = True, 1  # light
    occ[:, 45:47] = True  # untagged: code 0
    grid = OccupancyGrid(occ, 0.1, 0.0, 0.0, materials=codes)
    table = np.array([3.4, 2.2, 3.4, 14.8, 1.9, 0.6])
    assert wall_loss_cells(grid, 5, 0, 5, 59, table) == (3, pytest.approx(14.8 + 2.2 + 3.4))
    assert wall_loss_cells(grid, 5, 59, 5, 20, table) == (2, pytest.approx(3.4 + 2.2))
    walls, loss = wall_loss_many(grid, (0.05, 0.55), np.array([[5.95, 0.55], [2.05, 0.55], [0.55, 0.95]]), table)
    assert walls.tolist() == [3, 1, 0]
    np.testing.assert_allclose(loss, [14.8 + 2.2 + 3.4, 14.8, 0.0])
    # without materials every wall costs the untagged price
    plain = OccupancyGrid(occ, 0.1, 0.0, 0.0)
    assert wall_loss_cells(plain, 5, 0, 5, 59, table) == (3, pytest.approx(3 * 3.4))
    np.testing.assert_allclose(wall_loss_many(plain, (0.05, 0.55), np.array([[5.95, 0.55]]), table)[1], [3 * 3.4])


def test_vectorised_loss_equals_scalar_on_the_office():
    from rescuemesh.radio import BleParams
    from rescuemesh.radio.walls import wall_loss_cells, wall_loss_many

    office = load_map(office_map_path())
    table = BleParams().loss_by_code
    rng = np.random.default_rng(5)
    a = (3.0, 8.0)
    pts = rng.uniform((0.2, 0.2), (19.3, 9.0), size=(300, 2))
    walls, loss = wall_loss_many(office.grid, a, pts, table)
    r0, c0 = office.grid.world_to_cell(*a)
    for p, w, l in zip(pts, walls, loss):
        assert wall_loss_cells(office.grid, r0, c0, *office.grid.world_to_cell(*p), table) == (w, pytest.approx(l))


def test_a_wall_is_priced_by_its_dearest_cell_where_materials_meet():
    # this used to price a wall by the cell the path entered it through: a path entering a
    # light partition where it meets a concrete wall paid the partition's 2.2 dB (stripes on the map)
    from rescuemesh.radio.walls import wall_loss_cells, wall_loss_many

    occ = np.zeros((10, 40), dtype=bool)
    codes = np.zeros((10, 40), dtype=np.uint8)
    occ[5, 10:14], codes[5, 10:14] = True, 1  # light partition, met end-on
    occ[:, 14:16], codes[:, 14:16] = True, 3  # concrete wall across the path
    grid = OccupancyGrid(occ, 0.1, 0.0, 0.0, materials=codes)
    table = np.array([0.0, 2.2, 3.4, 14.8, 1.9, 0.6])
    assert wall_loss_cells(grid, 5, 2, 5, 30, table) == (1, pytest.approx(14.8))
    np.testing.assert_allclose(wall_loss_many(grid, (0.25, 0.55), np.array([[3.05, 0.55]]), table)[1], [14.8])


# --- the wall loss averaged over the first Fresnel zone (issue 20) --------------------------------
_LAMBDA = 299_792_458.0 / 2.44e9


@pytest.fixture(scope="module")
def half_wall() -> OccupancyGrid:
    """4 m x 4 m at 0.05 m: a wall 0.1 m thick at x 2.0..2.1 from y = 0 up to y = 2.0 (its end),
    untagged (code 0)."""
    occ = np.zeros((80, 80), dtype=bool)
    occ[:40, 40:42] = True
    return OccupancyGrid(occ, 0.05, 0.0, 0.0)


def test_one_ray_is_the_straight_line():
    from rescuemesh.radio.walls import wall_loss_cells, wall_loss_fresnel

    office = load_map(office_map_path()).grid
    table = np.array([3.4, 2.2, 3.4, 14.8, 1.9, 0.6])
    rng = np.random.default_rng(2)
    for a, b in rng.uniform((0.2, 0.2), (19.3, 9.0), size=(200, 2, 2)):
        straight = wall_loss_cells(office, *office.world_to_cell(*a), *office.world_to_cell(*b), table)
        assert wall_loss_fresnel(office, tuple(a), tuple(b), table, _LAMBDA, 0.0, 1) == straight


def test_a_wall_end_costs_part_of_its_loss_across_the_fresnel_zone(half_wall):
    """Paths 3.95 m long crossing x = 2.05 at height y: the straight line pays the whole 10 dB below the
    wall's end (y < 2.0) and nothing above it; the bundle (9 rays over the first Fresnel zone, radius
    sqrt(lambda d / 4) = 0.35 m at the wall) ramps from 10 dB to 0 over about +-0.35 m."""
    from rescuemesh.radio.walls import wall_loss_fresnel

    table = np.array([10.0, 0, 0, 0, 0, 0])
    r1 = math.sqrt(_LAMBDA * 4.0 / 4)
    losses = []
    for y in np.arange(1.2, 2.8, 0.05):
        walls, loss = wall_loss_fresnel(half_wall, (0.025, y + 0.025), (3.975, y + 0.025), table, _LAMBDA, 0.0, 9)
        straight = wall_loss_fresnel(half_wall, (0.025, y + 0.025), (3.975, y + 0.025), table, _LAMBDA, 0.0, 1)
        assert walls == (1 if y < 2.0 else 0) and straight == (walls, 10.0 * walls)
        losses.append(loss)
        if y + 0.025 < 2.0 - r1 - 0.05:
            assert loss == pytest.approx(10.0)  # the whole zone is behind the wall
        elif y + 0.025 > 2.0 + r1 + 0.05:
            assert loss == 0.0  # the whole zone is clear
        elif abs(y + 0.025 - 2.0) < r1 - 0.05:
            assert 0.0 < loss < 10.0  # the end within the zone: part of the loss
    assert np.all(np.diff(losses) <= 1e-12)  # less loss as the path rises past the end
    at_end = wall_loss_fresnel(half_wall, (0.025, 1.975), (3.975, 1.975), table, _LAMBDA, 0.0, 9)[1]
    # half the rays blocked: -10 log10((5 + 4 / 10) / 9) = 2.2 dB, or with 5 blocked 3.0 dB
    assert 2.0 < at_end < 3.2


def test_the_bundle_is_the_same_both_ways_and_vectorised():
    from rescuemesh.radio import BleParams
    from rescuemesh.radio.walls import wall_loss_fresnel, wall_loss_fresnel_many

    office = load_map(office_map_path()).grid
    table = BleParams().loss_by_code
    free = np.argwhere(~office.occupied)
    rng = np.random.default_rng(9)
    centre = lambda rc: (office.origin_x + (rc[1] + 0.5) * 0.05, office.origin_y + (rc[0] + 0.5) * 0.05)  # noqa: E731
    a = centre(free[rng.integers(len(free))])
    pts = np.array([centre(rc) for rc in free[rng.choice(len(free), 300, replace=False)]])
    walls, loss = wall_loss_fresnel_many(office, a, pts, table, _LAMBDA, 0.3, 9)
    for p, w, l in zip(pts, walls, loss):
        assert wall_loss_fresnel(office, a, tuple(p), table, _LAMBDA, 0.3, 9) == (w, l)
        assert wall_loss_fresnel(office, tuple(p), a, table, _LAMBDA, 0.3, 9)[1] == pytest.approx(l, abs=1e-9)
        assert w == count_walls(office, a, tuple(p))
    assert np.any(loss != wall_loss_fresnel_many(office, a, pts, table, _LAMBDA, 0.3, 1)[1])
