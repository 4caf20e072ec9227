"""Planned paths as map-frame polylines, and the geometry the planner, controller and action share.

Owns: `Path`, `Polyline` and arc lengths. Must not know how a path was planned or how it is
followed; numpy and plain math only (the arc lengths compiled: nav/kernels.py).

`Polyline` answers the controller's questions (project the robot, a point at an arc length, the
part ahead) in plain Python floats over the few segments concerned. The navigation's every tick
asks them compiled (nav/pursuit_kernels.py, the same arithmetic, checked against this class in
tests/oracles/test_nav_pursuit.py); `compute_velocity` takes a Polyline as the path.
tests/nav/reference_polyline.py holds the same geometry over whole numpy arrays, and the tests
check that the two agree to rounding.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rescuemesh.nav import kernels


@dataclass(frozen=True, eq=False)
class Path:
    """A planned path: `points` is an (N, 2) float array of map-frame waypoints in m, N >= 1.

    The first point is the robot's start position, the last the goal position (or the free cell
    the goal was snapped to). `length_m` is the polyline length in m. A Path is never modified
    (its `cum` and `polyline` are computed on first use and kept).
    """

    points: np.ndarray
    length_m: float

    @classmethod
    def from_points(cls, points: np.ndarray) -> "Path":
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)  # the compiled controller reads it
        cum = cumulative_lengths(pts)
        path = cls(points=pts, length_m=float(cum[-1]))
        path.__dict__["cum"] = cum  # the cached property, known already
        return path

    def extended_to(self, x: float, y: float) -> "Path":
        """This path with one more waypoint (x, y) m: `Path.from_points` of the points and (x, y),
        without summing the earlier arc lengths again (compiled: nav/kernels.py, `append_vertex`)."""
        points, cum = kernels.append_vertex(np.ascontiguousarray(self.points, dtype=float),
                                            np.ascontiguousarray(self.cum, dtype=float), float(x), float(y))
        path = Path(points=points, length_m=float(cum[-1]))
        path.__dict__["cum"] = cum
        return path

    @property
    def end(self) -> np.ndarray:
        """The last waypoint (x, y) in m."""
        return self.points[-1]

    @cached_property
    def cum(self) -> np.ndarray:
        """Arc length in m at each vertex (`cumulative_lengths`), computed once."""
        return cumulative_lengths(self.points)

    @cached_property
    def polyline(self) -> "Polyline":
        """The path as a `Polyline` for cheap per-tick queries, computed once."""
        return Polyline.from_points(self.points, cum=self.cum)


def cumulative_lengths(points: np.ndarray) -> np.ndarray:
    """Arc length in m at each vertex of the (N, 2) polyline, starting at 0 (each step's hypot,
    summed in order; compiled: nav/kernels.py)."""
    return kernels.cumulative_lengths(np.ascontiguousarray(points, dtype=float).reshape(-1, 2))


class Polyline:
    """A polyline in plain Python floats with its per-vertex arc lengths, for per-tick queries.

    `xs`, `ys`: vertex coordinates in m (N >= 1); `cum`: arc length in m at each vertex; `length`:
    the total. `project`, `point_at` and `slice` only visit the segments in the requested arc-length
    window (found by bisection).
    """

    __slots__ = ("xs", "ys", "cum", "length")

    def __init__(self, xs: list[float], ys: list[float], cum: list[float]) -> None:
        self.xs, self.ys, self.cum = xs, ys, cum
        self.length = cum[-1] if cum else 0.0

    @classmethod
    def from_points(cls, points: np.ndarray, *, cum: np.ndarray | None = None) -> "Polyline":
        """From an (N, 2) array in m; `cum` its `cumulative_lengths` when already known."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        cum = cumulative_lengths(pts) if cum is None else cum
        return cls(pts[:, 0].tolist(), pts[:, 1].tolist(), cum.tolist())

    @classmethod
    def from_vertices(cls, xs: list[float], ys: list[float]) -> "Polyline":
        """From vertex coordinate lists in m (N >= 1); arc lengths summed as `cumulative_lengths` does."""
        cum, s = [0.0], 0.0
        for i in range(1, len(xs)):
            s += math.hypot(xs[i] - xs[i - 1], ys[i] - ys[i - 1])
            cum.append(s)
        return cls(xs, ys, cum)

    def __len__(self) -> int:
        return len(self.xs)

    def to_array(self) -> np.ndarray:
        """The vertices as an (N, 2) array in m."""
        return np.column_stack([self.xs, self.ys]).reshape(-1, 2)

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
