"""Planar ray casting on the map's walls as an occupancy grid: an exact cell walk, compiled with numba.

Owns: WallGrid (the walls rasterised for the lidar) and the cell walk. Must not know MuJoCo, robots
or when sweeps happen: lidar.py takes the nearer of this range and MuJoCo's (for everything else).

Theory of operation: a beam is the half-line p + t * d (t in m, d a unit vector in the plane). It is
clipped to the grid's rectangle and to `max_range`, then walks the cells it crosses in order
(Amanatides and Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987): at
each step it crosses the nearer of the next vertical and the next horizontal cell edge. Its range
is the distance at which it enters the first occupied cell, so the range is exact for walls made of
whole cells (ROS maps, and the office, whose walls lie on its 5 cm grid); a wall edge between cell
edges is moved out to the cell edge (`maps.raster.rasterise_walls`). Across open space the walk
jumps: a cell whose chessboard distance to the nearest wall cell is k has every cell within k - 1
free, so the beam skips to where it leaves that square and walks on from there (3x fewer steps in
the office). The cost is the cells crossed before a hit or `max_range` (at most about
1.41 * max_range / resolution), whatever the number of walls or the size of the map.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy import ndimage

from rescuemesh.maps.model import MapModel
from rescuemesh.maps.raster import rasterise_walls


#: Smallest clearance (cells) at which the walk jumps across free space instead of stepping.
_SKIP = 3


class WallGrid:
    """The map's walls (`MapModel.walls`, the physics world's static boxes) as an occupancy grid.

    Rasterised over `map_model.bounds` at the navigation grid's resolution, cell (0, 0) at the lower
    left (as `maps.grid.OccupancyGrid`). Not `map_model.grid`: that one also blocks unknown cells of a
    ROS map, which have no wall in the physics world. Walls are `map_model.wall_height` m tall: a beam
    plane above them sees none.
    """

    def __init__(self, map_model: MapModel) -> None:
        grid = rasterise_walls(map_model.walls, map_model.bounds, map_model.grid.resolution)
        self.occupied = np.ascontiguousarray(grid.occupied, dtype=np.uint8)
        #: Chessboard distance in cells from each cell to the nearest wall cell, at most 255 (no wall).
        self.clearance = _clearance(grid.occupied)
        self.resolution = float(grid.resolution)
        self.origin_x = float(grid.origin_x)
        self.origin_y = float(grid.origin_y)
        self.wall_height = float(map_model.wall_height)

    def cast(self, x: float, y: float, cos: np.ndarray, sin: np.ndarray, max_range: float, out: np.ndarray) -> None:
        """Ranges in m from (x, y) m along unit directions (cos[i], sin[i]) into `out[i]`; inf: no wall
        within `max_range` m. A start inside a wall cell reads 0."""
        _cast(
            self.occupied, self.clearance, self.origin_x, self.origin_y, self.resolution, float(x), float(y), cos, sin,
            float(max_range), out,
        )


def _clearance(occupied: np.ndarray) -> np.ndarray:
    if not occupied.any():
        return np.full(occupied.shape, 255, dtype=np.uint8)
    chess = ndimage.distance_transform_cdt(~occupied, metric="chessboard")
    return np.minimum(chess, 255).astype(np.uint8)


# Compiled when the module is imported (explicit signature), from numba's on-disk cache after the
# first time: the one-off cost (about 0.2 s to load, 1 s to compile) is not paid inside a run.
@numba.njit(
    "void(u1[:, ::1], u1[:, ::1], f8, f8, f8, f8, f8, f8[::1], f8[::1], f8, f8[::1])", cache=True, nogil=True
)
def _cast(occ, clear, ox, oy, res, x, y, cos, sin, max_range, out):  # pragma: no cover - compiled
    rows, cols = occ.shape
    gx = (x - ox) / res  # start in cell units
    gy = (y - oy) / res
    t_end = max_range / res
    for i in range(cos.shape[0]):
        out[i] = math.inf
        dx = cos[i]
        dy = sin[i]
        # Clip the beam [0, t_end] to the grid rectangle [0, cols] x [0, rows] (slab method).
        t0 = 0.0
        t1 = t_end
        if dx != 0.0:
            ta = -gx / dx
            tb = (cols - gx) / dx
            t0 = max(t0, min(ta, tb))
            t1 = min(t1, max(ta, tb))
        elif gx < 0.0 or gx >= cols:
            continue
        if dy != 0.0:
            ta = -gy / dy
            tb = (rows - gy) / dy
            t0 = max(t0, min(ta, tb))
            t1 = min(t1, max(ta, tb))
        elif gy < 0.0 or gy >= rows:
            continue
        if t0 > t1:
            continue
        step_c = 1 if dx > 0.0 else (-1 if dx < 0.0 else 0)
        step_r = 1 if dy > 0.0 else (-1 if dy < 0.0 else 0)
        delta_x = 1.0 / abs(dx) if dx != 0.0 else math.inf
        delta_y = 1.0 / abs(dy) if dy != 0.0 else math.inf
        t = t0
        c = min(max(int(math.floor(gx + t * dx)), 0), cols - 1)
        r = min(max(int(math.floor(gy + t * dy)), 0), rows - 1)
        while True:
            # Distance along the beam to the next vertical and horizontal cell edge of cell (r, c).
            next_x = ((c + (step_c > 0)) - gx) / dx if dx != 0.0 else math.inf
            next_y = ((r + (step_r > 0)) - gy) / dy if dy != 0.0 else math.inf
            k = clear[r, c]
            if k >= _SKIP:
                # Every cell within k - 1 of (r, c) is free: jump to where the beam leaves that square.
                lo_c, hi_c, lo_r, hi_r = c - k + 1, c + k - 1, r - k + 1, r + k - 1
                ex = ((c + k if step_c > 0 else lo_c) - gx) / dx if dx != 0.0 else math.inf
                ey = ((r + k if step_r > 0 else lo_r) - gy) / dy if dy != 0.0 else math.inf
                t = min(ex, ey)
                if t > t1:
                    break
                if ex <= ey:
                    c = hi_c + 1 if step_c > 0 else lo_c - 1
                else:
                    c = min(max(int(math.floor(gx + t * dx)), lo_c), hi_c)
                if ey <= ex:
                    r = hi_r + 1 if step_r > 0 else lo_r - 1
                else:
                    r = min(max(int(math.floor(gy + t * dy)), lo_r), hi_r)
                if c < 0 or c >= cols or r < 0 or r >= rows:
                    break
                continue
            # Walk cell by cell until a wall, the grid's edge or the end of the beam.
            while t <= t1:
                if occ[r, c]:
                    out[i] = t * res
                    break
                if next_x < next_y:
                    t = next_x
                    next_x += delta_x
                    c += step_c
                    if c < 0 or c >= cols:
                        break
                else:
                    t = next_y
                    next_y += delta_y
                    r += step_r
                    if r < 0 or r >= rows:
                        break
                if clear[r, c] >= _SKIP:
                    break
            else:
                break  # past the end of the beam
            if out[i] < math.inf or c < 0 or c >= cols or r < 0 or r >= rows or t > t1:
                break
