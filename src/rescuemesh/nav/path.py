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
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rescuemesh.nav import kernels, pursuit_kernels


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

    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The vertices ((N, 2) m) and arc lengths as the compiled kernels take them (N >= 1)."""
        if not self.xs:
            raise ValueError("an empty Polyline has no points")
        return np.column_stack([self.xs, self.ys]).reshape(-1, 2), np.asarray(self.cum, dtype=float)

    def point_at(self, s: float) -> tuple[float, float]:
        """(x, y) in m at arc length `s` m, clamped to the ends (`np.interp`'s arithmetic; compiled:
        nav/pursuit_kernels.py, as every geometry below)."""
        return pursuit_kernels.point_at(*self._arrays(), float(s))

    def project(self, x: float, y: float, *, s_min: float = 0.0, s_max: float = math.inf) -> tuple[float, float]:
        """Project the point (x, y) m onto the polyline: (arc length s in m of the nearest point,
        distance in m to it), searching only segments overlapping [s_min, s_max], so a path that
        passes near itself twice is not short-cut (Nav2's `max_robot_pose_search_dist`)."""
        return pursuit_kernels.project_and_distance(*self._arrays(), float(x), float(y), float(s_min), float(s_max))

    def slice(self, s_start: float = 0.0, s_end: float = math.inf) -> "Polyline":
        """The part between arc lengths `s_start` and `s_end` m, as a new Polyline (N >= 1)."""
        xs, ys, cum = pursuit_kernels.slice_part(*self._arrays(), float(s_start), float(s_end))
        return Polyline(xs.tolist(), ys.tolist(), cum.tolist())
