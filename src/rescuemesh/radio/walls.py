"""How many walls a straight radio path crosses, counted on the map's occupancy grid.

Owns: the wall count of a segment (one, and one transmitter to many receivers). Must not know:
what a wall costs in dB, radios, the medium.

The path is the straight line between the cells holding its two ends, rasterised with Bresenham's
algorithm (the cells of `skimage.draw.line`): one cell per step along the major axis, so it never
skips a row or a column and no axis-aligned wall, however thin, can be jumped. A wall is a run of
occupied cells along it: the count is the number of free -> occupied transitions met walking from
`a` to `b`. So a wall two cells thick counts once; furniture counts like a wall; a cell off the
grid counts as occupied (the map's outside is solid). Starting inside an obstacle does not count
that obstacle; ending inside one does (the path entered it).

Why not sample the segment every half cell: Bresenham visits the same walls on axis-aligned maps,
is exact integer arithmetic, and costs one C call (about 8 us for a 15 m path with the look-ups,
less than half of sampling it with numpy). The vectorised version uses the closed form of the
same algorithm (cell i of a line whose major axis spans n cells has minor offset
floor((2 i |d_minor| + n) / (2 n))), so the two agree cell for cell (tests/radio/test_walls.py
compares them). Limitation: the line is 8-connected, so a diagonal wall one cell thick whose cells
touch only at corners can be slipped through; the office's walls are axis-aligned and two cells
thick.

A segment whose cells' bounding box holds no occupied cell crosses no wall: that box is summed in
O(1) from the grid's summed-area table before any line is drawn. In a team most pairs of robots
see each other across free floor (61 % of new pairs in the follow, 77 % in a 10-robot convoy).
"""

from __future__ import annotations

import math

import numpy as np
from skimage.draw import line as _bresenham

from rescuemesh.maps.grid import OccupancyGrid

#: Upper bound on cells held in memory at once by the vectorised count.
_CHUNK_CELLS = 2_000_000
#: Padded occupancy (a border of occupied cells all round) of the last few grids, by identity.
_PADDED: dict[int, tuple[OccupancyGrid, np.ndarray]] = {}
#: Summed-area tables of the last few grids' occupancy, by identity: S[r, c] = occupied cells in
#: rows < r and columns < c.
_SUMS: dict[int, tuple[OccupancyGrid, np.ndarray]] = {}


def _sums(grid: OccupancyGrid) -> np.ndarray:
    entry = _SUMS.get(id(grid))
    if entry is None or entry[0] is not grid:
        if len(_SUMS) >= 8:
            _SUMS.clear()
        table = np.zeros((grid.occupied.shape[0] + 1, grid.occupied.shape[1] + 1), dtype=np.int64)
        np.cumsum(np.cumsum(grid.occupied, axis=0, dtype=np.int64), axis=1, out=table[1:, 1:])
        entry = _SUMS[id(grid)] = (grid, table)
    return entry[1]


def _padded(grid: OccupancyGrid) -> np.ndarray:
    entry = _PADDED.get(id(grid))
    if entry is None or entry[0] is not grid:
        if len(_PADDED) >= 8:
            _PADDED.clear()
        entry = _PADDED[id(grid)] = (grid, np.pad(np.asarray(grid.occupied, dtype=bool), 1, constant_values=True))
    return entry[1]


def _occupied_cells(grid: OccupancyGrid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Occupancy of cells (row, col) of any shape; off the grid is occupied (the padded border)."""
    n_rows, n_cols = grid.occupied.shape
    rows = np.minimum(np.maximum(rows, -1), n_rows) + 1  # np.clip costs 4x more on small arrays
    cols = np.minimum(np.maximum(cols, -1), n_cols) + 1
    return _padded(grid)[rows, cols]


def _cell(grid: OccupancyGrid, x: float, y: float) -> tuple[int, int]:
    return (math.floor((y - grid.origin_y) / grid.resolution), math.floor((x - grid.origin_x) / grid.resolution))


def count_walls(grid: OccupancyGrid, a: tuple[float, float], b: tuple[float, float]) -> int:
    """Walls crossed on the straight path from `a` to `b` (points in m, frame map)."""
    r0, c0 = _cell(grid, float(a[0]), float(a[1]))
    r1, c1 = _cell(grid, float(b[0]), float(b[1]))
    n_rows, n_cols = grid.occupied.shape
    low_r, high_r, low_c, high_c = min(r0, r1), max(r0, r1) + 1, min(c0, c1), max(c0, c1) + 1
    on_grid = 0 <= low_r and high_r <= n_rows and 0 <= low_c and high_c <= n_cols
    if on_grid:  # the line stays in the box of its ends
        sums = _sums(grid).item
        if sums(high_r, high_c) - sums(low_r, high_c) - sums(high_r, low_c) + sums(low_r, low_c) == 0:
            return 0
    rows, cols = _bresenham(r0, c0, r1, c1)
    if on_grid:
        occ = grid.occupied[rows, cols]
    else:
        occ = _occupied_cells(grid, rows, cols)
    return int(np.count_nonzero(occ[1:] & ~occ[:-1]))


def count_walls_many(grid: OccupancyGrid, a: tuple[float, float], points: np.ndarray) -> np.ndarray:
    """Walls crossed from `a` to each of `points` (shape (N, 2), m); int array of shape (N,).

    Equal to `count_walls(grid, a, p)` for every p. Shorter lines are padded with their end cell,
    which adds no transition.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.zeros(len(pts), dtype=np.int64)
    if len(pts) == 0:
        return out
    r0, c0 = _cell(grid, float(a[0]), float(a[1]))
    r1 = np.floor((pts[:, 1] - grid.origin_y) / grid.resolution).astype(np.int64)
    c1 = np.floor((pts[:, 0] - grid.origin_x) / grid.resolution).astype(np.int64)
    dr, dc = r1 - r0, c1 - c0
    n = np.maximum(np.abs(dr), np.abs(dc))  # steps along the major axis
    order = np.argsort(n, kind="stable")  # chunks of similar length waste little padding
    size = max(1, _CHUNK_CELLS // (int(n.max()) + 1))
    for start in range(0, len(pts), size):
        idx = order[start:start + size]
        ni = n[idx, None]
        i = np.minimum(np.arange(int(ni.max()) + 1)[None, :], ni)  # padded with the end cell
        steps = np.maximum(ni, 1)
        adr, adc = np.abs(dr[idx, None]), np.abs(dc[idx, None])
        sr, sc = np.sign(dr[idx, None]), np.sign(dc[idx, None])
        col_major = adc >= adr
        minor = (2 * i * np.where(col_major, adr, adc) + steps) // (2 * steps)
        rows = r0 + sr * np.where(col_major, minor, i)
        cols = c0 + sc * np.where(col_major, i, minor)
        occ = _occupied_cells(grid, rows, cols)
        out[idx] = np.count_nonzero(occ[:, 1:] & ~occ[:, :-1], axis=1)
    return out
