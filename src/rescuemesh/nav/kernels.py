"""The navigation's per-tick geometry, compiled: a scan's obstacle cells, the lethal check of points
against the costmap and its scan obstacles, and the controller's swept-footprint clearance.

Owns: these loops over arrays. Must not know: Costmap, paths, robots, time (nav/costmap.py and
nav/controller.py call them with plain arrays and numbers).
"""

# Each runs once or twice per robot per 50 ms tick over a few hundred scan points or path samples:
# as numpy they were a few dozen calls of about a microsecond each, most of the navigation's time.
# The arithmetic is numpy's, element by element (floor, hypot, atan2, sqrt): the same numbers and
# the same decisions as the numpy they replaced (tests/oracles/test_nav_kernels.py).

from __future__ import annotations

import math

import numpy as np

from rescuemesh.jit import compiled

_HALF_PI = math.pi / 2
_TWO_PI = 2.0 * math.pi


@compiled("Tuple((i8[::1], i8[::1]))(f8[:, ::1], f8, f8, f8, i8, i8, b1[::1], f8, f8, f8)")
def scan_obstacle_cells(points, origin_x, origin_y, resolution, rows, cols, stampable, clear_x, clear_y,
                        clear_radius):
    """The scan points that are obstacles of their own: on the grid, in a cell where `stampable`
    (flat, row-major) is True, and farther than `clear_radius` m from (clear_x, clear_y) (a radius
    <= 0 clears nothing). Returns (their indices in `points`, in order; the distinct flat cells
    holding them, sorted)."""
    n = points.shape[0]
    kept = np.empty(n, dtype=np.int64)
    flat = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        x, y = points[i, 0], points[i, 1]
        fc = np.floor((x - origin_x) / resolution)
        fr = np.floor((y - origin_y) / resolution)
        if not (0.0 <= fc < cols and 0.0 <= fr < rows):  # also NaN and inf: off the grid
            continue
        cell = int(fr) * cols + int(fc)
        if not stampable[cell]:
            continue
        if clear_radius > 0.0 and not math.hypot(x - clear_x, y - clear_y) > clear_radius:
            continue
        kept[m] = i
        flat[m] = cell
        m += 1
    cells = np.sort(flat[:m])
    distinct = 0
    for j in range(m):
        if j == 0 or cells[j] != cells[j - 1]:
            cells[distinct] = cells[j]
            distinct += 1
    return kept[:m].copy(), cells[:distinct].copy()


@compiled("b1(f8[::1], f8[::1], f8, f8, f8, i8, i8, b1[::1], i8[::1], i8[::1], b1[:, ::1], f8, f8, f8)")
def any_lethal(xs, ys, origin_x, origin_y, resolution, rows, cols, lethal, obstacle_rows, obstacle_cols, disc,
               clear_x, clear_y, clear_radius):
    """Whether any point (xs[i], ys[i]) m farther than `clear_radius` from (clear_x, clear_y) (all
    points when the radius is <= 0) is off the grid, on a cell where `lethal` (flat) is True, or in
    the lethal part (`disc`, centred, (2n+1) square) of an obstacle cell's inflation kernel."""
    reach = disc.shape[0] // 2
    for i in range(len(xs)):
        x, y = xs[i], ys[i]
        if clear_radius > 0.0 and not math.hypot(x - clear_x, y - clear_y) > clear_radius:
            continue
        fc = np.floor((x - origin_x) / resolution)
        fr = np.floor((y - origin_y) / resolution)
        if not (0.0 <= fc < cols and 0.0 <= fr < rows):
            return True
        row, col = int(fr), int(fc)
        if lethal[row * cols + col]:
            return True
        for j in range(len(obstacle_rows)):
            dr = row - obstacle_rows[j]
            dc = col - obstacle_cols[j]
            if -reach <= dr <= reach and -reach <= dc <= reach and disc[dr + reach, dc + reach]:
                return True
    return False


@compiled("f8(f8[:, ::1], f8, f8, f8, f8, f8, f8, f8, f8)")
def scan_clearance(points, x0, y0, yaw, max_range, curvature, footprint_radius, corridor_margin, horizon):
    """Free distance in m ahead of the footprint along the arc of `curvature` (1/m) driven from pose
    (x0, y0, yaw), to the map points `points` within `max_range` m (inf: all) that lie in the swept
    corridor; inf when none does (nav/controller.py, `obstacle_clearance`, says which count)."""
    c, s = math.cos(yaw), math.sin(yaw)
    half = footprint_radius + corridor_margin
    straight = abs(curvature) < 1e-3
    r = 1.0 / curvature if not straight else 0.0
    best = math.inf
    for i in range(points.shape[0]):
        dx, dy = points[i, 0] - x0, points[i, 1] - y0
        if max_range < math.inf and not dx * dx + dy * dy <= max_range * max_range:
            continue
        x, y = c * dx + s * dy, -s * dx + c * dy
        if straight:
            if not (x >= 0.0 and abs(y) <= half):
                continue
            along, lateral = x, abs(y)
        else:
            lateral = abs(math.hypot(x, y - r) - abs(r))
            if not lateral <= half:
                continue
            ang = math.atan2(y - r, x)
            phi = (ang + _HALF_PI) % _TWO_PI if r > 0 else (_HALF_PI - ang) % _TWO_PI
            if not phi <= math.pi:
                continue
            along = abs(r) * phi
        lat = min(lateral, footprint_radius)
        gap = along - math.sqrt(footprint_radius**2 - lat**2)
        if gap <= horizon and gap < best:
            best = gap
    return best
