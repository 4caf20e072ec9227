"""Oracles of the navigation kernels (nav/kernels.py): the numpy that nav/costmap.py and
nav/controller.py ran before they were compiled, as functions of plain arrays."""

from __future__ import annotations

import math

import numpy as np


def cells_of(xy, origin_xy, resolution, shape):
    """Costmap.cells_of: (rows, cols, inside) of (N, 2) map points."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    size_wh = np.array(shape[::-1], dtype=np.uint64)
    with np.errstate(invalid="ignore"):
        cr = np.floor((xy - origin_xy) / resolution).astype(np.int64)
    ok = cr.view(np.uint64) < size_wh
    return cr[:, 1], cr[:, 0], ok[:, 0] & ok[:, 1]


def scan_obstacle_cells(pts, origin_xy, resolution, shape, stampable, clear_center, clear_radius):
    """Costmap.with_obstacles' selection: (indices of the points kept, their distinct flat cells, sorted)."""
    w = shape[1]
    rows, cols, inside = cells_of(pts, origin_xy, resolution, shape)
    kept = np.flatnonzero(inside)
    flat = (rows * w + cols)[kept]
    keep = stampable[flat]
    kept, flat = kept[keep], flat[keep]
    if clear_center is not None and clear_radius > 0.0 and len(flat):
        near = pts[kept]
        far = np.hypot(near[:, 0] - clear_center[0], near[:, 1] - clear_center[1]) > clear_radius
        kept, flat = kept[far], flat[far]
    return kept, np.unique(flat)


def any_lethal(xs, ys, origin_xy, resolution, shape, lethal, obstacle_rc, disc):
    """Costmap.any_lethal: any point off the grid, on a lethal cell of `lethal` (2-D), or in the lethal
    `disc` of an obstacle cell (rows, cols) (the disc comparison of _near_obstacle)."""
    rows = np.floor((ys - origin_xy[1]) / resolution).astype(np.int64)
    cols = np.floor((xs - origin_xy[0]) / resolution).astype(np.int64)
    try:
        flat = np.ravel_multi_index((rows, cols), shape)
    except ValueError:
        return True
    if np.count_nonzero(lethal.reshape(-1)[flat]):
        return True
    orow, ocol = obstacle_rc
    dr = rows[:, None] - orow[None, :]
    dc = cols[:, None] - ocol[None, :]
    n = disc.shape[0] // 2
    near = (np.abs(dr) <= n) & (np.abs(dc) <= n)
    return bool(near.any() and disc[dr[near] + n, dc[near] + n].any())


def blocked(xs, ys, centre, clear_radius, *lethal_args):
    """NavigateToPose._blocked after its samples: lethal ahead, outside clear_radius of the goal."""
    if not any_lethal(xs, ys, *lethal_args):
        return False
    if clear_radius <= 0.0:
        return True
    far = np.hypot(xs - centre[0], ys - centre[1]) > clear_radius
    return bool(far.any()) and any_lethal(xs[far], ys[far], *lethal_args)


def robot_frame_xy(x0, y0, yaw, points, max_range=math.inf):
    """controller._robot_frame_xy."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    dx, dy = pts[:, 0] - x0, pts[:, 1] - y0
    if max_range < math.inf:
        near = dx * dx + dy * dy <= max_range * max_range
        dx, dy = dx[near], dy[near]
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def clearance(x, y, curvature, footprint_radius, corridor_margin, horizon):
    """controller._clearance."""
    if len(x) == 0:
        return math.inf
    half = footprint_radius + corridor_margin
    if abs(curvature) < 1e-3:
        inside = (x >= 0.0) & (np.abs(y) <= half)
        along, lateral = x[inside], np.abs(y[inside])
    else:
        r = 1.0 / curvature
        lateral = np.abs(np.hypot(x, y - r) - abs(r))
        band = lateral <= half
        x, y, lateral = x[band], y[band], lateral[band]
        ang = np.arctan2(y - r, x)
        phi = np.mod(ang + math.pi / 2, 2 * math.pi) if r > 0 else np.mod(math.pi / 2 - ang, 2 * math.pi)
        ahead = phi <= math.pi
        along, lateral = abs(r) * phi[ahead], lateral[ahead]
    if len(along) == 0:
        return math.inf
    lat = np.minimum(lateral, footprint_radius)
    extent = np.sqrt(footprint_radius**2 - lat**2)
    gap = along - extent
    gap = gap[gap <= horizon]
    return float(np.min(gap)) if len(gap) else math.inf
