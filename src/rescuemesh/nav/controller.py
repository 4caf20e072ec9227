"""Regulated pure pursuit (after Nav2's RPP controller) as pure functions of (pose, path, scan points).

Owns: ControllerParams, compute_velocity and its helpers (lookahead, curvature and approach
regulation, the swept-footprint obstacle check). Must not know: planning, goals' outcomes, time, robots.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav import kernels
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

    The geometry runs in plain floats on a `Polyline` (numpy only for the scan): a few segments
    per tick are far cheaper that way than as tiny numpy arrays.
    """
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
        clearance = kernels.scan_clearance(points, x, y, pose.yaw, obstacle_reach(params), curvature,
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
