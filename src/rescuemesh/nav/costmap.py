"""Costmap: an occupancy grid turned into traversal costs for a round robot, plus scan obstacles.

Owns: static inflation (scipy EDT, as Nav2's inflation layer) and the per-scan obstacle layer.
Must not know: where the grid or the scan points came from (no sim, no robot, no protocol), nor planning.

Theory of operation: every cell has a *clearance*, the distance in m from its centre to the nearest
obstacle surface (EDT distance to the nearest occupied cell centre minus half a cell). A cell whose
clearance is below `inscribed_radius` is LETHAL (cost 1.0): the robot's centre there would touch.
Beyond, the cost decays as Nav2's `exp(-cost_scaling * (clearance - inscribed_radius))` scaled to
[0, MAX_NON_LETHAL], and is 0 beyond `inflation_radius`. Scan obstacles are stamped with a
precomputed disc kernel of the same profile; only cells near the points are touched, and only over
the part of the map asked for (`cost_in`: a planner's search window) until the whole array is.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import kernels

LETHAL = 1.0
"""Cost of a cell the robot's centre may not enter."""

_NO_OBSTACLES = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))

MAX_NON_LETHAL = 0.99
"""Cost just outside the inscribed radius (Nav2's 252/254)."""


def inflation_cost(
    clearance: np.ndarray, inscribed_radius: float, inflation_radius: float, cost_scaling: float
) -> np.ndarray:
    """Cost in [0, 1] for clearances in m: LETHAL below `inscribed_radius`, 0 beyond `inflation_radius`.

    `cost_scaling` is in 1/m (Nav2 inflation layer `cost_scaling_factor`).
    """
    c = np.asarray(clearance, dtype=float)
    decay = MAX_NON_LETHAL * np.exp(-cost_scaling * np.maximum(c - inscribed_radius, 0.0))
    out = np.where(c > inflation_radius, 0.0, decay)
    return np.where(c < inscribed_radius, LETHAL, out).astype(np.float32)


def grid_clearance(grid: OccupancyGrid) -> np.ndarray:
    """Distance in m from each cell's centre to the nearest obstacle cell's surface (EDT distance
    to its centre minus half a cell); inf everywhere on a grid without obstacles."""
    occupied = np.asarray(grid.occupied, dtype=bool)
    if not occupied.any():
        return np.full(occupied.shape, np.inf)
    return ndimage.distance_transform_edt(~occupied) * grid.resolution - 0.5 * grid.resolution


class Costmap:
    """Traversal costs over an OccupancyGrid, in the grid's cells and frame.

    - `cost[row, col]`: float32 in [0, 1]; 1.0 (LETHAL) where the robot may not be; outside the grid is lethal.
    - `lethal[row, col]`: bool, `cost >= LETHAL`.
    - `static_clearance[row, col]`: m from the cell centre to the nearest map obstacle surface.
    - `obstacle_points`: (N, 2) map-frame points of the obstacle layer (m), `obstacle_stamp` their time (s).

    A Costmap is never modified after construction: `with_obstacles` returns a new one that shares
    the static arrays.
    """

    def __init__(
        self,
        grid: OccupancyGrid,
        *,
        inscribed_radius: float = 0.18,
        inflation_radius: float = 0.55,
        cost_scaling: float = 5.0,
    ) -> None:
        """Inflate `grid`. Radii in m (robot radius 0.177 m -> 0.18 m), `cost_scaling` in 1/m."""
        if inflation_radius < inscribed_radius:
            raise ValueError("inflation_radius must be >= inscribed_radius")
        self.grid = grid
        self.resolution = float(grid.resolution)
        self.inscribed_radius = float(inscribed_radius)
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling = float(cost_scaling)
        clearance = grid_clearance(grid)
        self.static_clearance = clearance.astype(np.float32)
        self.static_cost = inflation_cost(clearance, self.inscribed_radius, self.inflation_radius, self.cost_scaling)
        self._cost = self.static_cost
        self._lethal = self._static_lethal = self.static_cost >= LETHAL
        self._window: tuple[tuple[int, int, int, int], np.ndarray] | None = None  # the last `cost_in` stamped
        self._origin_xy = np.array([grid.origin_x, grid.origin_y], dtype=float)
        self._size_wh = np.array(self.shape[::-1], dtype=np.uint64)  # (cols, rows)
        # flat: cells where a scan point is an obstacle of its own (not on or next to a static one)
        self._stampable = (self.static_clearance >= 1.5 * self.resolution).reshape(-1)
        self._obstacle_cells = np.zeros(0, dtype=np.int64)
        self._obstacle_rc = np.divmod(self._obstacle_cells, self.shape[1])  # their rows and columns
        self.obstacle_points = np.zeros((0, 2))
        self._lethal_base: tuple | None = None  # see _lethal_args
        self.obstacle_stamp: float | None = None
        self._kernel = self._make_kernel()
        dr, dc, kval = self._kernel
        n = int(max(np.abs(dr).max(), np.abs(dc).max())) if len(dr) else 0
        self._kernel_reach = n  # cells: an obstacle cell's stamp ends this far from it
        self._lethal_disc = np.zeros((2 * n + 1, 2 * n + 1), dtype=bool)  # kernel offsets that are LETHAL
        self._lethal_disc[dr[kval >= LETHAL] + n, dc[kval >= LETHAL] + n] = True

    # -- geometry -------------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return self.static_cost.shape

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding map point (x, y) m; may lie outside the grid."""
        return self.grid.world_to_cell(x, y)

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Map-frame (x, y) in m of the centre of cell (row, col)."""
        return self.grid.cell_to_world(row, col)

    def cells_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, inside) int arrays for an (N, 2) array of map points in m."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        # x and y in one array: few numpy calls, each costs more than the work on a scan's points
        cr = np.floor((xy - self._origin_xy) / self.resolution).astype(np.int64)
        ok = cr.view(np.uint64) < self._size_wh  # (col, row) on the grid; a negative index is huge unsigned
        return cr[:, 1], cr[:, 0], ok[:, 0] & ok[:, 1]

    # -- queries --------------------------------------------------------------------------------

    def cost_at(self, x: float, y: float) -> float:
        """Cost in [0, 1] at map point (x, y) m; LETHAL (1.0) outside the grid."""
        row, col = self.world_to_cell(x, y)
        h, w = self.shape
        if not (0 <= row < h and 0 <= col < w):
            return LETHAL
        if self._cost is None and self._window is not None:
            (r0, r1, c0, c1), part = self._window
            if r0 <= row < r1 and c0 <= col < c1:
                return float(part[row - r0, col - c0])
        return float(self.cost[row, col])

    def is_free(self, x: float, y: float) -> bool:
        """True when the robot's centre may be at (x, y) m: inside the grid and not lethal."""
        return self.cost_at(x, y) < LETHAL

    def costs_at(self, xy: np.ndarray) -> np.ndarray:
        """Costs in [0, 1] at an (N, 2) array of map points in m; LETHAL outside the grid."""
        rows, cols, inside = self.cells_of(xy)
        out = np.full(len(rows), LETHAL, dtype=np.float32)
        rows, cols = rows[inside], cols[inside]
        if self._cost is None and self._window is not None and len(rows):
            (r0, r1, c0, c1), part = self._window  # points within the stamped window: no whole-map stamp
            if r0 <= rows.min() and rows.max() < r1 and c0 <= cols.min() and cols.max() < c1:
                out[inside] = part[rows - r0, cols - c0]
                return out
        out[inside] = self.cost[rows, cols]
        return out

    def any_lethal(self, xs: np.ndarray, ys: np.ndarray, *, clear_center: tuple[float, float] | None = None,
                   clear_radius: float = 0.0) -> bool:
        """True when any of the map points (xs[i], ys[i]) in m is lethal (`costs_at(...) >= LETHAL`) or off
        the grid, leaving out those within `clear_radius` m of `clear_center`. Without the full cost
        array, a point is lethal on a static lethal cell or in the lethal part of a scan obstacle
        cell's kernel: the same answer as the stamped array, without stamping the map (compiled)."""
        xs = np.ascontiguousarray(xs, dtype=float)
        ys = np.ascontiguousarray(ys, dtype=float)
        return kernels.any_lethal(xs, ys, *self._lethal_args(clear_center, clear_radius))

    def any_lethal_along(self, points: np.ndarray, cum: np.ndarray, s0: float, s1: float, step: float, *,
                         clear_center: tuple[float, float] | None = None, clear_radius: float = 0.0) -> bool:
        """`any_lethal` of the polyline `points` ((N, 2) m, arc lengths `cum` m at its vertices)
        sampled every `step` m from arc length `s0` to before `s1` (`np.arange`, then `np.interp`,
        which clamps to the ends): one compiled call."""
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
        cum = np.ascontiguousarray(cum, dtype=float)
        return kernels.path_any_lethal(pts, cum, float(s0), float(s1), float(step),
                                       *self._lethal_args(clear_center, clear_radius))

    def segment_any_lethal(self, a: tuple[float, float], b: tuple[float, float], samples: int) -> bool:
        """`any_lethal` of `samples` (>= 2) points evenly spaced from a to b (m), both included
        (`np.linspace`): one compiled call."""
        return kernels.segment_any_lethal(float(a[0]), float(a[1]), float(b[0]), float(b[1]), int(samples),
                                          *self._lethal_args(None, 0.0)[:-3])

    def _lethal_args(self, clear_center: tuple[float, float] | None, clear_radius: float) -> tuple:
        """The arguments of kernels.any_lethal after the points: the grid, the lethal cells, the
        obstacle cells when not stamped, the lethal disc and the cleared circle."""
        cx, cy = clear_center if clear_center is not None and clear_radius > 0.0 else (0.0, 0.0)
        radius = clear_radius if clear_center is not None else 0.0
        base = self._lethal_base  # the grid's part, kept while the lethal array stays (asked every tick)
        if base is None or base[0] is not self._lethal:
            h, w = self.shape
            if self._lethal is not None:
                lethal, (orow, ocol) = self._lethal.reshape(-1), _NO_OBSTACLES
            else:
                lethal, (orow, ocol) = self._static_lethal.reshape(-1), self._obstacle_rc
            base = self._lethal_base = (self._lethal, (self.grid.origin_x, self.grid.origin_y, self.resolution, h, w,
                                                       lethal, orow, ocol, self._lethal_disc))
        return base[1] + (cx, cy, radius)

    def clearance_at(self, x: float, y: float) -> float:
        """Distance in m from (x, y) to the nearest static map obstacle (0 outside the grid)."""
        row, col = self.world_to_cell(x, y)
        h, w = self.shape
        if not (0 <= row < h and 0 <= col < w):
            return 0.0
        return float(self.static_clearance[row, col])

    # -- obstacle layer -------------------------------------------------------------------------

    def static(self) -> "Costmap":
        """This costmap without its obstacle layer."""
        return self.with_obstacles(np.zeros((0, 2)), self.obstacle_stamp)

    def with_obstacles(
        self,
        points: np.ndarray,
        now: float | None,
        *,
        clear_center: tuple[float, float] | None = None,
        clear_radius: float = 0.0,
    ) -> "Costmap":
        """A new costmap: the static layer plus `points` ((N, 2) map-frame m, e.g. a scan) inflated.

        The obstacle layer is replaced, not accumulated (cleared and refreshed per scan). Points
        within `clear_radius` m of `clear_center` are ignored (the follower's leader near its goal).
        Points on or next to a static obstacle (clearance < 1.5 cells) are already in the static
        layer and skipped. `now` (s) is kept as `obstacle_stamp`.
        """
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
        out = object.__new__(Costmap)
        out.__dict__.update(self.__dict__)
        out.obstacle_stamp = now
        # this runs for every scan, mostly on points of static walls (compiled: nav/kernels.py)
        h, w = self.shape
        cx, cy = clear_center if clear_center is not None else (0.0, 0.0)
        kept, cells, rows, cols = kernels.scan_obstacle_cells(pts, self.grid.origin_x, self.grid.origin_y,
                                                              self.resolution, h, w, self._stampable, cx, cy,
                                                              clear_radius if clear_center is not None else 0.0)
        out.obstacle_points = kept
        out._cost = out._lethal = None  # built on first use: a blocked-path check does not need them
        out._window = None
        out._obstacle_cells = cells
        out._obstacle_rc = (rows, cols)
        out._lethal_base = None
        if len(cells) == 0:
            out._cost, out._lethal = self.static_cost, self._static_lethal
        return out

    @property
    def obstacle_cells(self) -> np.ndarray:
        """Sorted flat indices (row * cols + col) of the cells holding obstacle-layer points: two
        costmaps sharing `static_cost` with equal `obstacle_cells` have equal costs."""
        return self._obstacle_cells

    @property
    def cost(self) -> np.ndarray:
        if self._cost is None:
            self._stamp_obstacles()
        return self._cost

    @property
    def lethal(self) -> np.ndarray:
        if self._lethal is None:
            self._stamp_obstacles()
        return self._lethal

    def cost_in(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """`cost[r0:r1, c0:c1]` (clipped to the grid), stamping only the obstacle cells whose
        inflation reaches that window when the whole array is not built yet. The last window is
        kept: `cost_at` and `costs_at` of points inside it read it instead of stamping the map."""
        h, w = self.shape
        r0, r1, c0, c1 = max(r0, 0), min(r1, h), max(c0, 0), min(c1, w)
        if self._cost is not None:
            return self._cost[r0:r1, c0:c1]
        key = (r0, r1, c0, c1)
        if self._window is None or self._window[0] != key:
            self._window = (key, self._stamped(*key))
        return self._window[1]

    def known_costs(self) -> tuple[np.ndarray, int, int]:
        """(costs, row, col of its first cell): the whole `cost` array when it is built, else the
        last window `cost_in` stamped, else the whole array (stamped now). Compiled readers
        (nav/kernels.py) take cells inside it from it and the whole array for any other."""
        if self._cost is None and self._window is not None:
            (r0, _, c0, _), part = self._window
            return part, r0, c0
        return self.cost, 0, 0

    def _stamp_obstacles(self) -> None:
        """The full cost array: the static layer with every obstacle cell's inflation kernel stamped."""
        h, w = self.shape
        self._cost = self._stamped(0, h, 0, w)
        self._lethal = self._cost >= LETHAL

    def _stamped(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """A copy of `static_cost[r0:r1, c0:c1]` (within the grid) with the inflation kernel of
        every obstacle cell stamped where it reaches (the highest cost wins; compiled)."""
        cost = self.static_cost[r0:r1, c0:c1]
        if len(self._obstacle_cells) == 0:
            return cost.copy()
        dr, dc, kval = self._kernel
        orow, ocol = self._obstacle_rc
        return kernels.stamped(cost, r0, c0, orow, ocol, dr, dc, kval, self._kernel_reach)

    def _make_kernel(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cell offsets (drow, dcol) and costs of one obstacle cell, inflated: the stamp for scan points."""
        n = int(math.ceil(self.inflation_radius / self.resolution)) + 1
        dr, dc = np.mgrid[-n : n + 1, -n : n + 1]
        clearance = np.hypot(dr, dc) * self.resolution - 0.5 * self.resolution
        kval = inflation_cost(clearance, self.inscribed_radius, self.inflation_radius, self.cost_scaling)
        nz = kval > 0.0
        return dr[nz].astype(np.int64), dc[nz].astype(np.int64), kval[nz]
