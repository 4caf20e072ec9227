"""radio/walls.py: walls crossed on a straight segment of the occupancy grid."""

from __future__ import annotations

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
