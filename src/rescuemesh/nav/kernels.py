"""The navigation's hot loops, compiled: per sweep a scan's obstacle cells; per tick the lethal check
of points (a path's samples, a straight extension's) against the costmap and its scan obstacles,
the controller's swept-footprint clearance, and a follower's path grown by one waypoint; per plan
stamping scan obstacles into a window, the planner's coarse grid and step costs (written into its
search graph's array), the bound on paths leaving its window, reading a search's path back,
shortcutting, and arc lengths.

Owns: these loops over arrays. Must not know: Costmap, paths, robots, time (nav/costmap.py,
nav/controller.py, nav/planner.py, nav/path.py call them with plain arrays and numbers).
"""

# Each runs once or twice per robot per 50 ms tick over a few hundred scan points or path samples,
# or once per plan over the search window: as numpy they were a few dozen calls of about a
# microsecond each, most of the navigation's time. The arithmetic is numpy's, element by element
# and in numpy's order (floor, hypot, atan2, sqrt; np.arange's, np.interp's and np.linspace's
# formulas; float32 where the costs are): the same numbers and the same decisions as the numpy
# they replaced (tests/oracles/test_nav_kernels.py, test_nav_plan_kernels.py).

from __future__ import annotations

import math

import numpy as np

from rescuemesh.jit import compiled, compiled_on_first_call

_HALF_PI = math.pi / 2
_TWO_PI = 2.0 * math.pi


@compiled("Tuple((f8[:, ::1], i8[::1], i8[::1], i8[::1]))(f8[:, ::1], f8, f8, f8, i8, i8, b1[::1], f8, f8, f8)")
def scan_obstacle_cells(points, origin_x, origin_y, resolution, rows, cols, stampable, clear_x, clear_y,
                        clear_radius):
    """The scan points that are obstacles of their own: on the grid, in a cell where `stampable`
    (flat, row-major) is True, and farther than `clear_radius` m from (clear_x, clear_y) (a radius
    <= 0 clears nothing). Returns (those points, in order; the distinct flat cells holding them,
    sorted; those cells' rows and columns, np.divmod(cells, cols))."""
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
    cell_rows = np.empty(distinct, dtype=np.int64)
    cell_cols = np.empty(distinct, dtype=np.int64)
    for j in range(distinct):
        cell_rows[j] = cells[j] // cols
        cell_cols[j] = cells[j] - cell_rows[j] * cols
    kept_points = np.empty((m, 2))
    for j in range(m):
        kept_points[j, 0], kept_points[j, 1] = points[kept[j], 0], points[kept[j], 1]
    return kept_points, cells[:distinct].copy(), cell_rows, cell_cols


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


@compiled()  # no signature: compiled into its callers, not loaded at import
def arange(start, stop, step):
    """`np.arange(start, stop, step)` for step > 0, with numpy's arithmetic: its length is
    ceil((stop - start) / step), its values start, start + step, then start + i * d, where d is
    (start + step) - start."""
    q = math.ceil((stop - start) / step)
    n = int(q) if q > 0 else 0
    out = np.empty(n)
    if n > 0:
        out[0] = start
    if n > 1:
        out[1] = start + step
        d = out[1] - start
        for i in range(2, n):
            out[i] = start + i * d
    return out


@compiled()  # no signature: compiled into its callers, not loaded at import
def interp(x, xp, fp):
    """`np.interp(x, xp, fp)` (xp increasing, len >= 1) with numpy's arithmetic: clamped to fp's
    ends, fp[j] at x == xp[j], else the slope of segment j times (x - xp[j]) plus fp[j]."""
    n = len(xp)
    out = np.empty(len(x))
    for i in range(len(x)):
        v = x[i]
        if n == 1:  # (numpy's answer for nan too)
            out[i] = fp[0]
            continue
        if math.isnan(v):
            out[i] = v
            continue
        if v < xp[0]:
            out[i] = fp[0]
            continue
        if v >= xp[n - 1]:
            out[i] = fp[n - 1]
            continue
        lo, hi = 0, n - 1  # xp[lo] <= v < xp[hi]: the last j with xp[j] <= v
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if xp[mid] <= v:
                lo = mid
            else:
                hi = mid
        j = lo
        if xp[j] == v:
            out[i] = fp[j]
            continue
        slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
        y = slope * (v - xp[j]) + fp[j]
        if math.isnan(y):
            y = slope * (v - xp[j + 1]) + fp[j + 1]
            if math.isnan(y) and fp[j] == fp[j + 1]:
                y = fp[j]
        out[i] = y
    return out


@compiled_on_first_call("b1(f8[:, ::1], f8[::1], f8, f8, f8, f8, f8, f8, i8, i8, b1[::1], i8[::1], i8[::1], "
                        "b1[:, ::1], f8, f8, f8)")
def path_any_lethal(points, cum, s0, s1, step, origin_x, origin_y, resolution, rows, cols, lethal, obstacle_rows,
                    obstacle_cols, disc, clear_x, clear_y, clear_radius):
    """`any_lethal` of the path (`points`, arc lengths `cum`) sampled every `step` m from arc length
    s0 up to s1 (`arange`, `interp`): whether the path ahead crosses a lethal cell."""
    s = arange(s0, s1, step)
    xs = interp(s, cum, points[:, 0])
    ys = interp(s, cum, points[:, 1])
    return any_lethal(xs, ys, origin_x, origin_y, resolution, rows, cols, lethal, obstacle_rows, obstacle_cols, disc,
                      clear_x, clear_y, clear_radius)



_LETHAL32 = np.float32(1.0)  # costmap.LETHAL, as the float32 costs hold it


@compiled_on_first_call("b1[:, ::1](f4[:, :], i8, i8, i8, f4, f8[::1, :])")
def coarse_step_costs(cost, k, rows, cols, weight, step):
    """The planner's coarse grid of (`rows`, `cols`) blocks of k x k cells of `cost` (float32 in
    [0, 1]; a block's cells past cost's edge count as lethal): returns lethal (the block's highest
    cost is LETHAL) and writes into `step[:rows, :cols]` the cost of a step into each block, 1 +
    weight * that highest cost in float32, inf when lethal; the rest of `step` (at least rows x
    cols, Fortran order: the array MCP_Geometric reads) becomes inf (impassable)."""
    h, w = cost.shape
    lethal = np.empty((rows, cols), dtype=np.bool_)
    step[:, :] = math.inf
    one = np.float32(1.0)
    for r in range(rows):
        for c in range(cols):
            top = np.float32(0.0)
            first = True
            for dr in range(k):
                rr = r * k + dr
                for dc in range(k):
                    cc = c * k + dc
                    v = cost[rr, cc] if rr < h and cc < w else _LETHAL32
                    if first or v > top:
                        top = v
                        first = False
            is_lethal = top >= _LETHAL32
            lethal[r, c] = is_lethal
            step[r, c] = math.inf if is_lethal else np.float64(one + weight * top)
    return lethal


@compiled()  # no signature: compiled into its callers, not loaded at import
def _cost_at(cost, r0, c0, rows, cols, origin_x, origin_y, resolution, x, y):
    """Cost of the grid cell holding (x, y): LETHAL off the grid, cost[row - r0, col - c0] inside
    `cost` (a window of the grid), -1 on the grid but outside the window (not known here)."""
    fc = np.floor((x - origin_x) / resolution)
    fr = np.floor((y - origin_y) / resolution)
    if not (0.0 <= fc < cols and 0.0 <= fr < rows):
        return _LETHAL32
    r, c = int(fr) - r0, int(fc) - c0
    if 0 <= r < cost.shape[0] and 0 <= c < cost.shape[1]:
        return cost[r, c]
    return np.float32(-1.0)


@compiled()  # no signature: compiled into its callers, not loaded at import
def _segment_max_cost(points, i, e, samples, f, cost, r0, c0, rows, cols, origin_x, origin_y, resolution):
    """Highest cost along the segment points[i] -> points[e] at the `samples` fractions `f`; -1 when
    a sample is on the grid outside `cost`."""
    ax, ay = points[i, 0], points[i, 1]
    dx, dy = points[e, 0] - ax, points[e, 1] - ay
    top = np.float32(0.0)
    for t in range(samples):
        v = _cost_at(cost, r0, c0, rows, cols, origin_x, origin_y, resolution, ax + f[t] * dx, ay + f[t] * dy)
        if v < 0.0:
            return v
        if t == 0 or v > top:
            top = v
    return top


@compiled_on_first_call("i8[::1](f8[:, ::1], f4[:, :], i8, i8, i8, i8, f8, f8, f8, f8, f4)")
def shortcut_kept(points, cost, r0, c0, rows, cols, origin_x, origin_y, resolution, max_segment_m, cost_tolerance):
    """Indices of the points of a cell path (N > 2, m) that line-of-sight shortcutting keeps
    (nav/planner.py, `shortcut`, says the rule), the costs read from `cost`, the window of the
    (rows, cols) grid starting at cell (r0, c0); empty when a sample falls on the grid outside it."""
    n = points.shape[0]
    missing = np.zeros(0, dtype=np.int64)
    raw = np.empty(n, dtype=np.float32)
    for p in range(n):
        raw[p] = _cost_at(cost, r0, c0, rows, cols, origin_x, origin_y, resolution, points[p, 0], points[p, 1])
        if raw[p] < 0.0:
            return missing
    cum = np.empty(n)
    cum[0] = 0.0
    for p in range(1, n):
        cum[p] = cum[p - 1] + math.hypot(points[p, 0] - points[p - 1, 0], points[p, 1] - points[p - 1, 1])
    kept = np.empty(n, dtype=np.int64)
    kept[0] = 0
    m = 1
    limit = np.empty(n, dtype=np.float32)
    i = 0
    while i < n - 1:
        reach = cum[i] + max_segment_m
        j = i  # the last point whose arc length is <= reach (np.searchsorted(..., side="right") - 1)
        while j + 1 < n and cum[j + 1] <= reach:
            j += 1
        j = min(max(j, i + 1), n - 1)
        if j > i + 1:  # (the raw step itself is always allowed)
            top = raw[i]
            longest = 0.0
            for e in range(i + 1, j + 1):
                top = max(top, raw[e])
                limit[e] = top + cost_tolerance
                longest = max(longest, math.hypot(points[e, 0] - points[i, 0], points[e, 1] - points[i, 1]))
            samples = max(2, int(math.ceil(longest / (0.75 * resolution))) + 1)
            f = np.empty(samples)
            step = 1.0 / (samples - 1)  # np.linspace(0, 1, samples)
            for t in range(samples - 1):
                f[t] = t * step
            f[samples - 1] = 1.0
            seg = _segment_max_cost(points, i, j, samples, f, cost, r0, c0, rows, cols, origin_x, origin_y,
                                    resolution)
            if seg < 0.0:
                return missing
            if not (seg < _LETHAL32 and seg <= limit[j]):
                last = i + 1
                for e in range(i + 1, j + 1):
                    seg = _segment_max_cost(points, i, e, samples, f, cost, r0, c0, rows, cols, origin_x,
                                            origin_y, resolution)
                    if seg < 0.0:
                        return missing
                    if e == i + 1 or (seg < _LETHAL32 and seg <= limit[e]):
                        last = e
                j = last
        i = j
        kept[m] = i
        m += 1
    return kept[:m].copy()


@compiled_on_first_call("f4[:, ::1](f4[:, :], i8, i8, i8[::1], i8[::1], i8[::1], i8[::1], f4[::1], i8)")
def stamped(cost, r0, c0, obstacle_rows, obstacle_cols, kernel_rows, kernel_cols, kernel_costs, reach):
    """A copy of `cost` (the window of the grid from cell (r0, c0)) where each cell holds the
    highest of its cost and the costs `kernel_costs` that the inflation kernel (cell offsets
    kernel_rows, kernel_cols, at most `reach` cells) of every obstacle cell puts on it."""
    h, w = cost.shape
    out = np.empty((h, w), dtype=np.float32)
    for r in range(h):
        for c in range(w):
            out[r, c] = cost[r, c]
    for j in range(len(obstacle_rows)):
        orow, ocol = obstacle_rows[j] - r0, obstacle_cols[j] - c0
        if not (-reach <= orow < h + reach and -reach <= ocol < w + reach):
            continue
        for i in range(len(kernel_costs)):
            r, c = orow + kernel_rows[i], ocol + kernel_cols[i]
            if 0 <= r < h and 0 <= c < w and kernel_costs[i] > out[r, c]:
                out[r, c] = kernel_costs[i]
    return out


@compiled_on_first_call("b1(f8, f8, f8, f8, i8, f8, f8, f8, i8, i8, b1[::1], i8[::1], i8[::1], b1[:, ::1])")
def segment_any_lethal(ax, ay, bx, by, samples, origin_x, origin_y, resolution, rows, cols, lethal, obstacle_rows,
                       obstacle_cols, disc):
    """`any_lethal` of `samples` (>= 2) points evenly spaced from (ax, ay) to (bx, by), both ends
    included (np.linspace's arithmetic: a + (i / (samples - 1)) * (b - a), the last exactly b)."""
    f = np.empty(samples)
    step = 1.0 / (samples - 1)
    for t in range(samples - 1):
        f[t] = t * step
    f[samples - 1] = 1.0
    dx, dy = bx - ax, by - ay
    xs = np.empty(samples)
    ys = np.empty(samples)
    for t in range(samples):
        xs[t] = ax + f[t] * dx
        ys[t] = ay + f[t] * dy
    return any_lethal(xs, ys, origin_x, origin_y, resolution, rows, cols, lethal, obstacle_rows, obstacle_cols, disc,
                      0.0, 0.0, 0.0)


@compiled_on_first_call("f8[::1](f8[:, ::1])")
def cumulative_lengths(points):
    """Arc length at each vertex of the (N, 2) polyline `points`, from 0 (the hypot of each step,
    summed in order, as np.cumsum does)."""
    n = points.shape[0]
    cum = np.zeros(n)
    for i in range(1, n):
        cum[i] = cum[i - 1] + math.hypot(points[i, 0] - points[i - 1, 0], points[i, 1] - points[i - 1, 1])
    return cum


@compiled()
def _side_bound(cum, field, use_field, r0, c0, row, col, across, gr, gc, n, along_rows):
    """The least cum + rest along one side of the window (its row `row` or its column `col`)."""
    best = math.inf
    for i in range(n):
        r, c = (i, col) if along_rows else (row, i)
        if use_field:
            rest = field[r0 + r, c0 + c]
        else:
            rest = math.hypot(float(across), float(i - (gr if along_rows else gc)))
        value = cum[r, c] + rest
        if value < best:
            best = value
    return best


@compiled_on_first_call("f8(f8[:, :], i8, i8, i8, i8, i8, i8, b1, b1, b1, b1, f8[:, :], b1)")
def exit_bound(cum, r0, r1, c0, c1, gr, gc, top, bottom, left, right, field, use_field):
    """The planner's bound on a path leaving the window (nav/planner.py, `_exit_bound`): over the
    window's sides that are present (border a cell of the map), the least cost `cum` on the side
    plus the rest: hypot(cells across to the goal's mirror image, cells along from the goal), or
    `field` (whole map, at the window's offset) when `use_field`. inf when no side is present."""
    h, w = cum.shape
    bound = math.inf
    if top:
        bound = min(bound, _side_bound(cum, field, use_field, r0, c0, 0, 0, gr + 2, gr, gc, w, False))
    if bottom:
        bound = min(bound, _side_bound(cum, field, use_field, r0, c0, h - 1, 0, h + 1 - gr, gr, gc, w, False))
    if left:
        bound = min(bound, _side_bound(cum, field, use_field, r0, c0, 0, 0, gc + 2, gr, gc, h, True))
    if right:
        bound = min(bound, _side_bound(cum, field, use_field, r0, c0, 0, w - 1, w + 1 - gc, gr, gc, h, True))
    return bound


@compiled_on_first_call("Tuple((f8[:, ::1], f8[::1]))(f8[:, ::1], f8[::1], f8, f8)")
def append_vertex(points, cum, x, y):
    """(points with (x, y) appended, their arc lengths): `cum` (the arc lengths of `points`) and one
    more, as `cumulative_lengths` sums it."""
    n = points.shape[0]
    out = np.empty((n + 1, 2))
    out[:n] = points
    out[n, 0], out[n, 1] = x, y
    lengths = np.empty(n + 1)
    lengths[:n] = cum
    lengths[n] = cum[n - 1] + math.hypot(x - points[n - 1, 0], y - points[n - 1, 1])
    return out, lengths


@compiled_on_first_call("i8[:, ::1](i2[:, :], i8, i8, i8[:, ::1])")
def trace_back(traceback, row, col, offsets):
    """The cells (k, 2) of the cheapest path from a search's start to (row, col), start first, read
    from MCP's `traceback` array (at each cell, the index in `offsets` of the step that reached it;
    -1 at a start): what scikit-image's MCP.traceback returns, as an array."""
    limit = traceback.shape[0] * traceback.shape[1]
    n, r, c = 1, row, col
    while traceback[r, c] != -1:
        step = traceback[r, c]
        if step < 0 or step >= offsets.shape[0] or n > limit:
            raise ValueError("no path was found to this cell")
        r -= offsets[step, 0]
        c -= offsets[step, 1]
        n += 1
    cells = np.empty((n, 2), dtype=np.int64)
    r, c = row, col
    for k in range(n - 1, -1, -1):
        cells[k, 0], cells[k, 1] = r, c
        if k:
            step = traceback[r, c]
            r -= offsets[step, 0]
            c -= offsets[step, 1]
    return cells
