"""The controller's per-tick geometry, compiled: projecting the robot onto its path, cutting the part
ahead, and the regulated-pure-pursuit command on it (lookahead point, curvature, the regulations,
the scan's swept-footprint clearance), in one call per tick.

Owns: these loops over a path's vertex arrays (with CPython's math.hypot, rescuemesh/pymath.py). Must not know:
Path, Polyline, poses, robots, time (nav/path.py, nav/controller.py and nav/navigate.py call them
with arrays).
"""

# The same arithmetic as the Python it replaced (Polyline.project, .slice and .point_at, which now
# call these kernels, and compute_velocity's body; kept in tests/oracles/nav.py and checked there on
# random and recorded inputs): operation for operation, Python's min/max/bisect comparisons, and
# Python's own hypot, which is not libm's (rescuemesh/pymath.py says why that matters).

from __future__ import annotations

import math

import numpy as np

from rescuemesh.jit import compiled, compiled_on_first_call
from rescuemesh.nav.kernels import scan_clearance
from rescuemesh.pymath import py_hypot


# the controller's parameters, in the order `params` arrays hold them (nav/controller.py, _param_vector)
MAX_LINEAR, MAX_ANGULAR, MIN_LOOKAHEAD, MAX_LOOKAHEAD, LOOKAHEAD_TIME, ROTATE_ANGLE, ROTATE_GAIN = range(7)
MIN_ROTATE, DEADBAND, MIN_RADIUS, APPROACH, MIN_APPROACH, FOOTPRINT, MARGIN, STOP, SLOW = range(7, 16)
END_MARGIN, SEARCH, REACH = range(16, 19)
N_PARAMS = 19


@compiled()
def _max(a, b):
    """Python's max(a, b): a unless b > a."""
    return b if b > a else a


@compiled()
def _min(a, b):
    """Python's min(a, b): a unless b < a."""
    return b if b < a else a


@compiled()
def _bisect_right(a, n, x, lo):
    """bisect.bisect_right(a[:n], x, lo)."""
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if x < a[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@compiled()
def _bisect_left(a, n, x, lo):
    """bisect.bisect_left(a[:n], x, lo)."""
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@compiled()
def _point_at(xs, ys, cum, n, s):
    """Polyline.point_at: (x, y) at arc length s, clamped to the ends."""
    s = _min(_max(s, 0.0), cum[n - 1])
    j = _bisect_right(cum, n, s, 0) - 1
    if j >= n - 1 or cum[j] == s:
        return xs[j], ys[j]
    h = cum[j + 1] - cum[j]
    return (xs[j + 1] - xs[j]) / h * (s - cum[j]) + xs[j], (ys[j + 1] - ys[j]) / h * (s - cum[j]) + ys[j]


@compiled()
def _project(xs, ys, cum, n, x, y, s_min, s_max):
    """(arc length, distance) of the point nearest (x, y) on the segments overlapping [s_min, s_max]."""
    if n == 1:
        return 0.0, py_hypot(x - xs[0], y - ys[0])
    lo, hi = s_min, _max(s_min, s_max)
    first = max(_bisect_left(cum, n, lo, 1) - 1, 0)
    last = min(_bisect_right(cum, n, hi, 0) - 1, n - 2)
    if first > last:
        first = last = n - 2
    best_s, best_d = 0.0, math.inf
    for i in range(first, last + 1):
        x0, y0, c0, c1 = xs[i], ys[i], cum[i], cum[i + 1]
        dx, dy = xs[i + 1] - x0, ys[i + 1] - y0
        len2 = dx * dx + dy * dy
        t = ((x - x0) * dx + (y - y0) * dy) / (len2 if len2 > 0.0 else 1.0)
        s = c0 + _min(_max(t, 0.0), 1.0) * math.sqrt(len2)
        s = _min(_max(s, _max(c0, lo)), _min(c1, hi))
        if s == c1:
            px, py = xs[i + 1], ys[i + 1]
        elif s == c0:
            px, py = x0, y0
        else:
            px, py = dx / (c1 - c0) * (s - c0) + x0, dy / (c1 - c0) * (s - c0) + y0
        d = py_hypot(px - x, py - y)
        if d < best_d or i == first:
            best_s, best_d = s, d
    return best_s, best_d


@compiled_on_first_call("f8(f8[:, ::1], f8[::1], f8, f8, f8, f8)")
def project(points, cum, x, y, s_min, s_max):
    """Polyline.project(x, y, s_min=s_min, s_max=s_max)[0] of the polyline `points` ((N, 2), N >= 1,
    arc lengths `cum`): the arc length in m of the point nearest (x, y) in the window."""
    return _project(points[:, 0], points[:, 1], cum, points.shape[0], x, y, s_min, s_max)[0]


@compiled_on_first_call("UniTuple(f8, 2)(f8[:, ::1], f8[::1], f8, f8, f8, f8)")
def project_and_distance(points, cum, x, y, s_min, s_max):
    """`project` with the distance in m from (x, y) to the point found (Polyline.project)."""
    return _project(points[:, 0], points[:, 1], cum, points.shape[0], x, y, s_min, s_max)


@compiled_on_first_call("UniTuple(f8, 2)(f8[:, ::1], f8[::1], f8)")
def point_at(points, cum, s):
    """(x, y) at arc length `s` of the polyline `points` (arc lengths `cum`), clamped to the ends."""
    return _point_at(points[:, 0], points[:, 1], cum, points.shape[0], s)


@compiled()
def _rotate_toward(error, prm):
    """controller.rotate_toward."""
    if abs(error) < prm[DEADBAND]:
        return 0.0
    w = _max(prm[MIN_ROTATE], _min(prm[MAX_ANGULAR], prm[ROTATE_GAIN] * abs(error)))
    return math.copysign(w, error)


@compiled()
def _lookahead_point(xs, ys, cum, n, x, y, s_robot, lookahead):
    """controller._lookahead_point: where the path beyond the projection leaves the lookahead circle."""
    first_later = _bisect_right(cum, n, s_robot, 0)
    if first_later >= n:
        return xs[n - 1], ys[n - 1]
    px, py = _point_at(xs, ys, cum, n, s_robot)
    if py_hypot(px - x, py - y) >= lookahead:
        return px, py
    for k in range(first_later, n):
        qx, qy = xs[k], ys[k]
        if py_hypot(qx - x, qy - y) >= lookahead:
            p0x, p0y, dx, dy = px - x, py - y, qx - px, qy - py
            a, b = dx * dx + dy * dy, 2.0 * (p0x * dx + p0y * dy)
            c = p0x * p0x + p0y * p0y - lookahead * lookahead
            t = (-b + math.sqrt(_max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a) if a > 0.0 else 1.0
            t = _min(_max(t, 0.0), 1.0)
            return px + t * dx, py + t * dy
        px, py = qx, qy
    return xs[n - 1], ys[n - 1]


@compiled()
def _command(xs, ys, cum, n, x, y, yaw, scan, prm, speed, has_goal_yaw, goal_yaw, xy_tolerance):
    """compute_velocity's body on the polyline (xs, ys, cum)[:n]: (v, omega)."""
    if n == 0:
        return 0.0, 0.0
    if py_hypot(xs[n - 1] - x, ys[n - 1] - y) <= xy_tolerance:
        if not has_goal_yaw:
            return 0.0, 0.0
        return 0.0, _rotate_toward((goal_yaw - yaw + math.pi) % (2.0 * math.pi) - math.pi, prm)
    s_robot = _project(xs, ys, cum, n, x, y, 0.0, prm[SEARCH])[0]
    remaining = cum[n - 1] - s_robot
    lookahead = _min(prm[MAX_LOOKAHEAD], _max(prm[MIN_LOOKAHEAD], speed * prm[LOOKAHEAD_TIME]))
    tx, ty = _lookahead_point(xs, ys, cum, n, x, y, s_robot, lookahead)
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = tx - x, ty - y
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    dist2 = lx * lx + ly * ly
    if dist2 < 1e-12:
        return 0.0, 0.0
    heading_error = math.atan2(ly, lx)
    if abs(heading_error) > prm[ROTATE_ANGLE]:
        return 0.0, _rotate_toward(heading_error, prm)
    curvature = 2.0 * ly / dist2
    v = prm[MAX_LINEAR]
    if abs(curvature) > 1e-9 and 1.0 / abs(curvature) < prm[MIN_RADIUS]:
        v *= (1.0 / abs(curvature)) / prm[MIN_RADIUS]
    if remaining < prm[APPROACH]:
        v = _min(v, _max(prm[MIN_APPROACH], prm[MAX_LINEAR] * remaining / prm[APPROACH]))
    if scan.shape[0]:
        horizon = remaining + prm[END_MARGIN]
        clearance = scan_clearance(scan, x, y, yaw, prm[REACH], curvature, prm[FOOTPRINT], prm[MARGIN], horizon)
        # obstacle_speed_scale
        if clearance <= prm[STOP]:
            scale = 0.0
        else:
            span = prm[SLOW] - prm[STOP]
            scale = 1.0 if span <= 0 else _min(1.0, (clearance - prm[STOP]) / span)
        v *= scale
    omega = v * curvature
    if abs(omega) > prm[MAX_ANGULAR]:
        v *= prm[MAX_ANGULAR] / abs(omega)
        omega = math.copysign(prm[MAX_ANGULAR], omega)
    return v, omega


@compiled_on_first_call("UniTuple(f8, 2)(f8[:, ::1], f8[::1], f8, f8, f8, f8[:, ::1], f8[::1], f8, b1, f8, f8)")
def command(points, cum, x, y, yaw, scan, prm, speed, has_goal_yaw, goal_yaw, xy_tolerance):
    """compute_velocity on the polyline `points` ((N, 2) m, arc lengths `cum`) from pose (x, y, yaw):
    (v m/s, omega rad/s). `scan`: (M, 2) map points; `prm`: the parameters (see the names above);
    `speed`: the current speed's magnitude m/s; the goal yaw counts only when `has_goal_yaw`."""
    return _command(points[:, 0], points[:, 1], cum, points.shape[0], x, y, yaw, scan, prm, speed, has_goal_yaw,
                    goal_yaw, xy_tolerance)


@compiled()
def _slice(points, cum, s_start, s_end):
    """Polyline.slice(s_start, s_end) of the polyline `points` (arc lengths `cum`): (xs, ys, arc
    lengths, vertices used). Its vertices are the points at both arc lengths and those strictly
    between (one point when the part is shorter than 1e-9 m and holds no vertex), its arc lengths
    summed with Python's hypot (Polyline.from_vertices)."""
    n = points.shape[0]
    length = cum[n - 1]
    s0 = _min(_max(s_start, 0.0), length)
    s1 = _min(_max(s_end, s0), length)
    i0, i1 = _bisect_right(cum, n, s0, 0), _bisect_left(cum, n, s1, 0)
    xs, ys = points[:, 0], points[:, 1]
    x0, y0 = _point_at(xs, ys, cum, n, s0)
    inner = max(i1 - i0, 0)
    lx = np.empty(inner + 2)
    ly = np.empty(inner + 2)
    lc = np.empty(inner + 2)
    lx[0], ly[0], lc[0] = x0, y0, 0.0
    if i0 >= i1 and s1 - s0 <= 1e-9:
        return lx, ly, lc, 1
    for k in range(inner):
        lx[k + 1], ly[k + 1] = xs[i0 + k], ys[i0 + k]
    lx[inner + 1], ly[inner + 1] = _point_at(xs, ys, cum, n, s1)
    s = 0.0
    for k in range(1, inner + 2):
        s += py_hypot(lx[k] - lx[k - 1], ly[k] - ly[k - 1])
        lc[k] = s
    return lx, ly, lc, inner + 2


@compiled_on_first_call("Tuple((f8[::1], f8[::1], f8[::1]))(f8[:, ::1], f8[::1], f8, f8)")
def slice_part(points, cum, s_start, s_end):
    """Polyline.slice: the part of the polyline `points` between two arc lengths, as (xs, ys, arc lengths)."""
    lx, ly, lc, m = _slice(points, cum, s_start, s_end)
    return lx[:m], ly[:m], lc[:m]


@compiled_on_first_call("UniTuple(f8, 2)(f8[:, ::1], f8[::1], f8, f8, f8, f8, f8, f8[:, ::1], f8[::1], f8)")
def command_on_part(points, cum, s_start, s_end, x, y, yaw, scan, prm, speed):
    """`command` on Polyline.slice(s_start, s_end) of the polyline `points` (arc lengths `cum`, `_slice`).
    No goal yaw, no xy tolerance."""
    lx, ly, lc, m = _slice(points, cum, s_start, s_end)
    return _command(lx, ly, lc, m, x, y, yaw, scan, prm, speed, False, 0.0, 0.0)
