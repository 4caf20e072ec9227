"""Regulated pure pursuit (after Nav2's RPP controller) as pure functions of (pose, path, scan points).

Owns: ControllerParams, compute_velocity and its helpers (lookahead, curvature and approach
regulation, the swept-footprint obstacle check). Must not know: planning, goals' outcomes, time, robots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav import kernels, pursuit_kernels
from rescuemesh.nav.path import Polyline


@dataclass(frozen=True)
class ControllerParams:
    """Tuning for a TurtleBot 2 (Kobuki: radius 0.177 m, limits 0.7 m/s and pi rad/s)."""

    max_linear: float = 0.5  # cruise speed, m/s
    max_angular: float = 1.5  # rad/s
    min_lookahead: float = 0.4  # m
    max_lookahead: float = 0.6  # m
    lookahead_time: float = 1.2  # s: lookahead = speed * lookahead_time, clamped to [min, max]
    rotate_to_heading_angle: float = math.radians(60.0)  # rad: rotate in place above this heading error
    rotate_gain: float = 2.5  # rad/s of omega per rad of heading error, when rotating in place
    min_rotate_speed: float = 0.3  # rad/s: slowest in-place rotation (beats static friction)
    heading_deadband: float = 0.01  # rad: no rotation below this error at the goal
    regulated_min_radius: float = 0.9  # m: slow down on arcs tighter than this
    approach_distance: float = 0.6  # m: slow down linearly within this distance of the path end
    min_approach_linear: float = 0.05  # m/s: never slower than this while approaching
    footprint_radius: float = 0.18  # m: robot radius for the swept-corridor check
    corridor_margin: float = 0.02  # m: extra half-width of the corridor
    obstacle_stop_distance: float = 0.3  # m of free space ahead of the footprint below which v = 0
    obstacle_slow_distance: float = 1.0  # m of free space ahead of the footprint below which v is scaled
    obstacle_end_margin: float = 0.05  # m: obstacles beyond the footprint's reach at the path end + this are ignored
    path_search_distance: float = 2.0  # m along the path in which the robot is projected
    max_linear_accel: float | None = 1.0  # m/s^2 for speeding up (slowing down is never limited); None: off


def rotate_toward(heading_error: float, params: ControllerParams) -> float:
    """Angular speed in rad/s for an in-place rotation reducing `heading_error` (rad, target - yaw)."""
    if abs(heading_error) < params.heading_deadband:
        return 0.0
    w = max(params.min_rotate_speed, min(params.max_angular, params.rotate_gain * abs(heading_error)))
    return math.copysign(w, heading_error)


def to_robot_frame(pose: Pose2D, points: np.ndarray) -> np.ndarray:
    """(N, 2) map-frame points in m expressed in the robot frame (x forward, y left)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    dx, dy = pts[:, 0] - pose.x, pts[:, 1] - pose.y
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.stack((c * dx + s * dy, -s * dx + c * dy), axis=1)


def obstacle_clearance(
    points_robot: np.ndarray, curvature: float, params: ControllerParams, horizon: float = math.inf
) -> float:
    """Free distance in m ahead of the footprint along the arc of `curvature` (1/m) the robot drives.

    An obstacle point counts when it lies within the swept corridor (half-width footprint radius +
    margin), ahead of the robot's centre and within half a turn; its distance is the arc length to
    it minus the footprint's extent at its lateral offset. Points farther than `horizon` m (how far
    the robot will still drive, plus a margin) are ignored: a wall just beyond the goal does not
    stop the robot short of it. inf when the corridor is clear. (Compiled: nav/kernels.py.)
    """
    pts = np.ascontiguousarray(points_robot, dtype=float).reshape(-1, 2)
    return kernels.scan_clearance(pts, 0.0, 0.0, 0.0, math.inf, curvature, params.footprint_radius,
                                  params.corridor_margin, horizon)


def obstacle_reach(params: ControllerParams) -> float:
    """Distance in m from the robot's centre beyond which a scan point cannot change the speed scale.

    A counted point lies within the corridor half-width of the arc, so the arc length to it is at
    least its distance minus that half-width (an arc is no shorter than its chord), and its gap at
    least that minus the footprint radius; a gap beyond both the slow and the stop distance gives
    a scale of 1, as no point at all does. Plus 1 cm against rounding.
    """
    half = params.footprint_radius + params.corridor_margin
    return max(params.obstacle_slow_distance, params.obstacle_stop_distance) + half + params.footprint_radius + 0.01


def obstacle_speed_scale(clearance: float, params: ControllerParams) -> float:
    """Factor in [0, 1] on linear speed: 0 within the stop distance, 1 beyond the slow distance (m)."""
    if clearance <= params.obstacle_stop_distance:
        return 0.0
    span = params.obstacle_slow_distance - params.obstacle_stop_distance
    return 1.0 if span <= 0 else min(1.0, (clearance - params.obstacle_stop_distance) / span)


def limit_acceleration(v: float, previous_v: float, dt: float, params: ControllerParams) -> float:
    """`v` m/s with speeding-up limited to `max_linear_accel` over `dt` s; slowing down is immediate."""
    a = params.max_linear_accel
    if a is None or dt <= 0.0 or abs(v) <= abs(previous_v) or v * previous_v < 0:
        return v
    return math.copysign(min(abs(v), abs(previous_v) + a * dt), v)


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
    """One regulated-pure-pursuit command (v m/s, omega rad/s) to follow `path` ((N, 2) map m, or a Polyline).

    - Within `xy_tolerance` m of the path end: rotate in place to `goal_yaw` (rad), or (0, 0) without one.
    - Heading error to the lookahead point above `rotate_to_heading_angle`: rotate in place.
    - Otherwise drive the pure-pursuit arc through the lookahead point (at speed * lookahead_time m,
      clamped; `current_speed` m/s defaults to max_linear), slowed on tight arcs, near the path end,
      and for scan obstacles (`scan_points`, (M, 2) map m) in the swept footprint ahead before the
      path end: stopped within `obstacle_stop_distance`. The arc's curvature is kept when omega saturates.

    The lookahead point is where the path beyond the robot's projection (within
    `path_search_distance` of the path's start) first leaves the lookahead circle: candidates are
    the projection, then every vertex beyond it in order; the first one at least `lookahead` m
    away ends the search, and the circle is intersected with the segment to it (else the path end).
    One compiled call (nav/pursuit_kernels.py, `command`).
    """
    line = path if isinstance(path, Polyline) else Polyline.from_points(path)
    if len(line) == 0:
        return (0.0, 0.0)
    points = np.column_stack([line.xs, line.ys]).reshape(-1, 2)
    speed = params.max_linear if current_speed is None else abs(current_speed)
    return pursuit_kernels.command(points, np.asarray(line.cum, dtype=float), pose.x, pose.y, pose.yaw,
                                   _scan_array(scan_points), _param_vector(params), float(speed),
                                   goal_yaw is not None, 0.0 if goal_yaw is None else float(goal_yaw),
                                   float(xy_tolerance))


def command_on_part(pose: Pose2D, points: np.ndarray, cum: np.ndarray, s_start: float, s_end: float,
                    scan_points: np.ndarray | None, params: ControllerParams, current_speed: float) -> tuple[float, float]:
    """`compute_velocity(pose, Polyline.from_points(points, cum=cum).slice(s_start, s_end), scan_points,
    params, current_speed=current_speed)`: the command to follow the part of a path ((N, 2) m, arc
    lengths `cum` m) between two arc lengths, in one compiled call (the navigation's every tick)."""
    return pursuit_kernels.command_on_part(np.ascontiguousarray(points, dtype=float),
                                           np.ascontiguousarray(cum, dtype=float), s_start, s_end,
                                           pose.x, pose.y, pose.yaw, _scan_array(scan_points),
                                           _param_vector(params), abs(current_speed))


_NO_SCAN = np.zeros((0, 2))


def _scan_array(scan_points: np.ndarray | None) -> np.ndarray:
    if scan_points is None:
        return _NO_SCAN
    if type(scan_points) is np.ndarray and scan_points.dtype == np.float64 and scan_points.ndim == 2 \
            and scan_points.flags.c_contiguous:
        return scan_points  # a sweep's points as LaserScan.points_in_map gives them
    return np.ascontiguousarray(scan_points, dtype=float).reshape(-1, 2)


_VECTORS: dict[int, tuple[ControllerParams, np.ndarray]] = {}  # by id: hashing the dataclass costs more than the tick


def _param_vector(params: ControllerParams) -> np.ndarray:
    """The parameters the compiled controller reads, in nav/pursuit_kernels.py's order (kept per
    params object; shared: not to be written)."""
    kept = _VECTORS.get(id(params))
    if kept is None or kept[0] is not params:
        if len(_VECTORS) >= 64:
            _VECTORS.clear()
        kept = _VECTORS[id(params)] = (params, _vector_of(params))
    return kept[1]


def _vector_of(params: ControllerParams) -> np.ndarray:
    k = pursuit_kernels
    vec = np.empty(k.N_PARAMS)
    for index, value in ((k.MAX_LINEAR, params.max_linear), (k.MAX_ANGULAR, params.max_angular),
                         (k.MIN_LOOKAHEAD, params.min_lookahead), (k.MAX_LOOKAHEAD, params.max_lookahead),
                         (k.LOOKAHEAD_TIME, params.lookahead_time), (k.ROTATE_ANGLE, params.rotate_to_heading_angle),
                         (k.ROTATE_GAIN, params.rotate_gain), (k.MIN_ROTATE, params.min_rotate_speed),
                         (k.DEADBAND, params.heading_deadband), (k.MIN_RADIUS, params.regulated_min_radius),
                         (k.APPROACH, params.approach_distance), (k.MIN_APPROACH, params.min_approach_linear),
                         (k.FOOTPRINT, params.footprint_radius), (k.MARGIN, params.corridor_margin),
                         (k.STOP, params.obstacle_stop_distance), (k.SLOW, params.obstacle_slow_distance),
                         (k.END_MARGIN, params.obstacle_end_margin), (k.SEARCH, params.path_search_distance),
                         (k.REACH, obstacle_reach(params))):
        vec[index] = value
    return vec
