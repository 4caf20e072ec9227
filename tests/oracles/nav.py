"""Oracles of the navigation kernels (nav/kernels.py, pursuit_kernels.py, body_kernels.py): the numpy
and Python that nav/costmap.py, nav/controller.py, nav/navigate.py, nav/planner.py and body.py ran
before they were compiled, as functions of plain arrays (or of a Costmap, for the planner's
shortcutting), and the Python Polyline geometry the controller ran on."""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right

import numpy as np

from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav.controller import ControllerParams, obstacle_reach, obstacle_speed_scale, rotate_toward
from rescuemesh.nav.costmap import LETHAL
from rescuemesh.nav.kernels import scan_clearance
from rescuemesh.nav.path import Polyline as PackagePolyline


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


def path_samples(points, cum, s0, s1, step):
    """NavigateToPose._blocked's samples: every `step` m of arc length from s0 to before s1, clamped."""
    s = np.arange(s0, s1, step)  # np.interp clamps to the ends as point_at does
    return np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])


def points_in_map(ranges, angles, range_min, range_max, x, y, yaw):
    """LaserScan.points_in_map: the map points of the valid returns (angles: the beams' in the sensor frame)."""
    r = ranges
    ok = (r >= range_min) & (r <= range_max)  # False for nan, and for inf below a finite range_max
    if not math.isfinite(range_max):
        ok &= np.isfinite(r)
    r = r[ok]
    a = angles[ok] + yaw
    xy = np.empty((2, len(r)))
    np.multiply(r, np.cos(a, out=xy[0]), out=xy[0])
    np.multiply(r, np.sin(a, out=xy[1]), out=xy[1])
    xy[0] += x
    xy[1] += y
    return xy.T


def coarse_cost(cost, k, window):
    """MCPPlanner._coarse_cost: the highest cost of each k x k block of `window` (blocks past the
    map's edge lethal)."""
    r0, r1, c0, c1 = window
    if k == 1:
        return cost
    h, w = cost.shape
    padded = np.full(((r1 - r0) * k, (c1 - c0) * k), LETHAL, dtype=cost.dtype)
    padded[:h, :w] = cost
    out = padded[0::k, 0::k].copy()
    for dr in range(k):
        for dc in range(k):
            if dr or dc:
                np.maximum(out, padded[dr::k, dc::k], out=out)
    return out


def graph_costs(cost, k, window, cost_weight):
    """MCPPlanner._graph_over before the MCP graph: (coarse lethal mask, step costs handed to MCP_Geometric)."""
    coarse = coarse_cost(cost, k, window)
    lethal = coarse >= LETHAL
    return lethal, np.where(lethal, np.inf, 1.0 + cost_weight * coarse)


def segment_samples(costmap, a, bs):
    """planner.segment_samples: samples along each segment a -> bs[j]: every 0.75 cell along the longest."""
    longest = float(np.max(np.hypot(*(bs - a).T))) if len(bs) else 0.0
    return max(2, int(math.ceil(longest / (0.75 * costmap.resolution))) + 1)


def segment_max_costs(costmap, a, bs, samples=None):
    """planner.segment_max_costs: highest cost along each segment a -> bs[j], sampled `samples` times."""
    bs = np.asarray(bs, dtype=float).reshape(-1, 2)
    n = segment_samples(costmap, a, bs) if samples is None else samples
    f = np.linspace(0.0, 1.0, n)
    samples_xy = a[None, None, :] + f[None, :, None] * (bs - a)[:, None, :]
    return costmap.costs_at(samples_xy.reshape(-1, 2)).reshape(len(bs), n).max(axis=1)


def shortcut(costmap, points, *, max_segment_m=2.0, cost_tolerance=0.05):
    """planner.shortcut: line-of-sight shortcutting of a cell path on the costmap."""
    n = len(points)
    if n <= 2:
        return points
    raw_cost = costmap.costs_at(points)
    step = np.hypot(*np.diff(points, axis=0).T)
    cum = np.concatenate(([0.0], np.cumsum(step)))
    kept = [0]
    i = 0
    while i < n - 1:
        j = min(max(int(np.searchsorted(cum, cum[i] + max_segment_m, side="right")) - 1, i + 1), n - 1)
        if j > i + 1:  # (the raw step itself is always allowed)
            ends = points[i + 1 : j + 1]
            limit = np.maximum.accumulate(raw_cost[i : j + 1])[1:] + cost_tolerance
            samples = segment_samples(costmap, points[i], ends)
            seg = segment_max_costs(costmap, points[i], ends[-1:], samples)
            if not (seg[0] < LETHAL and seg[0] <= limit[-1]):
                seg = segment_max_costs(costmap, points[i], ends, samples)
                ok = (seg < LETHAL) & (seg <= limit)
                ok[0] = True
                j = i + 1 + int(np.flatnonzero(ok)[-1])
        i = j
        kept.append(i)
    return points[kept]


def stamped(static_cost, r0, r1, c0, c1, obstacle_rc, kernel, reach):
    """Costmap._stamped: static_cost[r0:r1, c0:c1] with every obstacle cell's inflation kernel
    (offsets and costs) stamped, the highest cost winning (stamped whole into a padded copy)."""
    cost = static_cost[r0:r1, c0:c1]
    if len(obstacle_rc[0]) == 0:
        return cost.copy()
    dr, dc, kval = kernel
    n = reach
    orow, ocol = obstacle_rc
    near = np.flatnonzero((orow >= r0 - n) & (orow < r1 + n) & (ocol >= c0 - n) & (ocol < c1 + n))
    if len(near) == 0:
        return cost.copy()
    hh, ww = cost.shape
    pad = 2 * n
    wide = ww + 2 * pad
    padded = np.zeros((hh + 2 * pad, wide), dtype=cost.dtype)
    padded[pad : pad + hh, pad : pad + ww] = cost
    centres = (orow[near] - (r0 - pad)) * wide + (ocol[near] - (c0 - pad))
    cells = (centres[:, None] + (dr * wide + dc)[None, :]).reshape(-1)
    np.maximum.at(padded.reshape(-1), cells, np.broadcast_to(kval, (len(near), len(kval))).reshape(-1))
    return padded[pad : pad + hh, pad : pad + ww].copy()


def segment_samples_between(a, b, samples):
    """NavigateToPose._extended's samples: `samples` points evenly from a to b (np.linspace)."""
    t = np.linspace(0.0, 1.0, samples)
    return a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])


def cumulative_lengths(points):
    """path.cumulative_lengths: arc length at each vertex of the (N, 2) polyline, from 0."""
    if len(points) < 2:
        return np.zeros(len(points))
    seg = np.hypot(*np.diff(points, axis=0).T)
    return np.concatenate(([0.0], np.cumsum(seg)))


# -- the controller (nav/controller.py before nav/pursuit_kernels.py) ---------------------------------


class Polyline(PackagePolyline):
    """nav/path.py's Polyline with its geometry (`point_at`, `project`, `slice`) in the Python it had
    before nav/pursuit_kernels.py compiled it; the rest is the package's, but for the arc lengths of
    `from_points`, which this module's Python sums (the package's are compiled)."""

    __slots__ = ()

    @classmethod
    def from_points(cls, points: np.ndarray, *, cum: np.ndarray | None = None) -> "Polyline":
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return super().from_points(pts, cum=cumulative_lengths(pts) if cum is None else cum)

    def point_at(self, s: float) -> tuple[float, float]:
        """(x, y) in m at arc length `s` m, clamped to the ends (`np.interp`'s arithmetic)."""
        cum, xs, ys = self.cum, self.xs, self.ys
        s = min(max(s, 0.0), self.length)
        j = bisect_right(cum, s) - 1
        if j >= len(cum) - 1 or cum[j] == s:
            return xs[j], ys[j]
        h = cum[j + 1] - cum[j]
        return (xs[j + 1] - xs[j]) / h * (s - cum[j]) + xs[j], (ys[j + 1] - ys[j]) / h * (s - cum[j]) + ys[j]

    def project(self, x: float, y: float, *, s_min: float = 0.0, s_max: float = math.inf) -> tuple[float, float]:
        """Project the point (x, y) m onto the polyline: (arc length s in m of the nearest point,
        distance in m to it), searching only segments overlapping [s_min, s_max], so a path that
        passes near itself twice is not short-cut (Nav2's `max_robot_pose_search_dist`)."""
        xs, ys, cum = self.xs, self.ys, self.cum
        n = len(xs)
        if n == 1:
            return 0.0, math.hypot(x - xs[0], y - ys[0])
        lo, hi = s_min, max(s_min, s_max)
        # segments i with cum[i + 1] >= lo and cum[i] <= hi; none: the last one, clamped
        first = max(bisect_left(cum, lo, 1) - 1, 0)
        last = min(bisect_right(cum, hi) - 1, n - 2)
        if first > last:
            first = last = n - 2
        best_s, best_d = 0.0, math.inf
        for i in range(first, last + 1):
            x0, y0, c0, c1 = xs[i], ys[i], cum[i], cum[i + 1]
            dx, dy = xs[i + 1] - x0, ys[i + 1] - y0
            len2 = dx * dx + dy * dy
            t = ((x - x0) * dx + (y - y0) * dy) / (len2 if len2 > 0.0 else 1.0)
            s = c0 + min(max(t, 0.0), 1.0) * math.sqrt(len2)
            s = min(max(s, max(c0, lo)), min(c1, hi))
            # point_at(s), inlined: s lies on this segment (its ends are its vertices)
            if s == c1:
                px, py = xs[i + 1], ys[i + 1]
            elif s == c0:
                px, py = x0, y0
            else:
                px, py = dx / (c1 - c0) * (s - c0) + x0, dy / (c1 - c0) * (s - c0) + y0
            d = math.hypot(px - x, py - y)
            if d < best_d or i == first:
                best_s, best_d = s, d
        return best_s, best_d

    def slice(self, s_start: float = 0.0, s_end: float = math.inf) -> "Polyline":
        """The part between arc lengths `s_start` and `s_end` m, as a new Polyline (N >= 1)."""
        cum = self.cum
        s0 = min(max(s_start, 0.0), self.length)
        s1 = min(max(s_end, s0), self.length)
        i0, i1 = bisect_right(cum, s0), bisect_left(cum, s1)  # inner vertices: s0 < cum < s1
        x0, y0 = self.point_at(s0)
        if i0 >= i1 and s1 - s0 <= 1e-9:
            return Polyline([x0], [y0], [0.0])
        x1, y1 = self.point_at(s1)
        return Polyline.from_vertices([x0, *self.xs[i0:i1], x1], [y0, *self.ys[i0:i1], y1])



def polyline_slice_command(pose, points, cum, s_start, s_end, scan_points, params, current_speed):
    """What NavigateToPose ran every tick: compute_velocity on the path's part between two arc lengths."""
    local = Polyline.from_points(points, cum=cum).slice(s_start, s_end)
    return compute_velocity(pose, local, scan_points, params, current_speed=current_speed)


def compute_velocity(
    pose: Pose2D,
    path: np.ndarray | Polyline,
    scan_points: np.ndarray | None,
    params: ControllerParams = ControllerParams(),
    *,
    goal_yaw: float | None = None,
    xy_tolerance: float = 0.0,
    current_speed: float | None = None,
) -> tuple[float, float]:
    """nav/controller.py's compute_velocity (its docstring says what it does) before it was compiled:
    plain floats on this module's Polyline."""
    if isinstance(path, PackagePolyline) and not isinstance(path, Polyline):
        path = Polyline(path.xs, path.ys, path.cum)
    line = path if isinstance(path, Polyline) else Polyline.from_points(path)
    if len(line) == 0:
        return (0.0, 0.0)
    x, y = pose.x, pose.y
    if math.hypot(line.xs[-1] - x, line.ys[-1] - y) <= xy_tolerance:
        if goal_yaw is None:
            return (0.0, 0.0)
        return (0.0, rotate_toward(wrap_angle(goal_yaw - pose.yaw), params))

    s_robot, _ = line.project(x, y, s_max=params.path_search_distance)
    remaining = line.length - s_robot
    speed = params.max_linear if current_speed is None else abs(current_speed)
    lookahead = min(params.max_lookahead, max(params.min_lookahead, speed * params.lookahead_time))
    tx, ty = _lookahead_point(line, x, y, s_robot, lookahead)
    # the lookahead point in the robot frame (to_robot_frame, in floats)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    dx, dy = tx - x, ty - y
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    dist2 = lx * lx + ly * ly
    if dist2 < 1e-12:
        return (0.0, 0.0)
    heading_error = math.atan2(ly, lx)
    if abs(heading_error) > params.rotate_to_heading_angle:
        return (0.0, rotate_toward(heading_error, params))

    curvature = 2.0 * ly / dist2
    v = params.max_linear
    if abs(curvature) > 1e-9 and 1.0 / abs(curvature) < params.regulated_min_radius:
        v *= (1.0 / abs(curvature)) / params.regulated_min_radius
    if remaining < params.approach_distance:
        v = min(v, max(params.min_approach_linear, params.max_linear * remaining / params.approach_distance))
    if scan_points is not None and len(scan_points):
        horizon = remaining + params.obstacle_end_margin
        points = np.ascontiguousarray(scan_points, dtype=float).reshape(-1, 2)
        clearance = scan_clearance(points, x, y, pose.yaw, obstacle_reach(params), curvature,
                                           params.footprint_radius, params.corridor_margin, horizon)
        v *= obstacle_speed_scale(clearance, params)
    omega = v * curvature
    if abs(omega) > params.max_angular:
        v *= params.max_angular / abs(omega)
        omega = math.copysign(params.max_angular, omega)
    return (float(v), float(omega))


def _lookahead_point(line: Polyline, x: float, y: float, s_robot: float, lookahead: float) -> tuple[float, float]:
    """Where the path beyond the robot's projection first leaves the `lookahead` m circle, else the path end.

    Candidates: the projection, then every vertex beyond it, in order; the first one at least
    `lookahead` m from (x, y) ends the search, and the circle is intersected with the segment to it.
    """
    xs, ys = line.xs, line.ys
    end = (xs[-1], ys[-1])
    first_later = bisect_right(line.cum, s_robot)
    if first_later >= len(xs):
        return end
    px, py = line.point_at(s_robot)
    if math.hypot(px - x, py - y) >= lookahead:
        return px, py
    for k in range(first_later, len(xs)):
        qx, qy = xs[k], ys[k]
        if math.hypot(qx - x, qy - y) >= lookahead:
            # intersection of the lookahead circle with the segment from p (inside) to q (outside)
            p0x, p0y, dx, dy = px - x, py - y, qx - px, qy - py
            a, b = dx * dx + dy * dy, 2.0 * (p0x * dx + p0y * dy)
            c = p0x * p0x + p0y * p0y - lookahead * lookahead
            t = (-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a) if a > 0.0 else 1.0
            t = min(max(t, 0.0), 1.0)
            return px + t * dx, py + t * dy
        px, py = qx, qy
    return end


def exit_bound(cum, window, goal, whole, field=None):
    """MCPPlanner's _exit_bound (nav/planner.py) before it was compiled."""
    r0, r1, c0, c1 = window
    h, w = cum.shape
    gr, gc = goal
    in_row, in_col = np.arange(w) - gc, np.arange(h) - gr  # offsets from the goal along a side
    sides = ((np.s_[0, :], gr + 2, in_row, r0 > whole[0]), (np.s_[-1, :], h + 1 - gr, in_row, r1 < whole[1]),
             (np.s_[:, 0], gc + 2, in_col, c0 > whole[2]), (np.s_[:, -1], w + 1 - gc, in_col, c1 < whole[3]))
    bound = math.inf
    for edge, across, along, present in sides:
        if present:
            rest = np.hypot(across, along) if field is None else field[r0:r1, c0:c1][edge]
            bound = min(bound, float(np.min(cum[edge] + rest)))
    return bound
