"""Regulated pure pursuit (after Nav2's RPP controller) as pure functions of (pose, path, scan points).

Owns: ControllerParams, compute_velocity and its helpers (lookahead, curvature and approach
regulation, the swept-footprint obstacle check). Must not know: planning, goals' outcomes, time, robots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav.path import cumulative_lengths, point_at, project


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
    d = np.asarray(points, dtype=float).reshape(-1, 2) - (pose.x, pose.y)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def obstacle_clearance(
    points_robot: np.ndarray, curvature: float, params: ControllerParams, horizon: float = math.inf
) -> float:
    """Free distance in m ahead of the footprint along the arc of `curvature` (1/m) the robot drives.

    An obstacle point counts when it lies within the swept corridor (half-width footprint radius +
    margin), ahead of the robot's centre and within half a turn; its distance is the arc length to
    it minus the footprint's extent at its lateral offset. Points farther than `horizon` m (how far
    the robot will still drive, plus a margin) are ignored: a wall just beyond the goal does not
    stop the robot short of it. inf when the corridor is clear.
    """
    if len(points_robot) == 0:
        return math.inf
    x, y = points_robot[:, 0], points_robot[:, 1]
    half = params.footprint_radius + params.corridor_margin
    if abs(curvature) < 1e-3:
        along, lateral = x, np.abs(y)
        ahead = x >= 0.0
    else:
        r = 1.0 / curvature  # signed: centre of the turn at (0, r)
        ang = np.arctan2(y - r, x)
        phi = np.mod(ang + math.pi / 2, 2 * math.pi) if r > 0 else np.mod(math.pi / 2 - ang, 2 * math.pi)
        along = abs(r) * phi
        lateral = np.abs(np.hypot(x, y - r) - abs(r))
        ahead = phi <= math.pi  # phi in [0, 2 pi): anticlockwise (left turn) or clockwise angle travelled
    inside = ahead & (lateral <= half)
    if not inside.any():
        return math.inf
    lat = np.minimum(lateral[inside], params.footprint_radius)
    extent = np.sqrt(params.footprint_radius**2 - lat**2)
    gap = along[inside] - extent
    gap = gap[gap <= horizon]
    return float(np.min(gap)) if len(gap) else math.inf


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
    path: np.ndarray,
    scan_points: np.ndarray | None,
    params: ControllerParams = ControllerParams(),
    *,
    goal_yaw: float | None = None,
    xy_tolerance: float = 0.0,
    current_speed: float | None = None,
) -> tuple[float, float]:
    """One regulated-pure-pursuit command (v m/s, omega rad/s) to follow `path` ((N, 2) map m).

    - Within `xy_tolerance` m of the path end: rotate in place to `goal_yaw` (rad), or (0, 0) without one.
    - Heading error to the lookahead point above `rotate_to_heading_angle`: rotate in place.
    - Otherwise drive the pure-pursuit arc through the lookahead point (at speed * lookahead_time m,
      clamped; `current_speed` m/s defaults to max_linear), slowed on tight arcs, near the path end,
      and for scan obstacles (`scan_points`, (M, 2) map m) in the swept footprint ahead before the
      path end: stopped within `obstacle_stop_distance`. The arc's curvature is kept when omega saturates.
    """
    pts = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return (0.0, 0.0)
    xy = np.array([pose.x, pose.y])
    end = pts[-1]
    if float(np.hypot(*(end - xy))) <= xy_tolerance:
        if goal_yaw is None:
            return (0.0, 0.0)
        return (0.0, rotate_toward(wrap_angle(goal_yaw - pose.yaw), params))

    cum = cumulative_lengths(pts)
    s_robot, _ = project(pts, xy, s_max=params.path_search_distance)
    remaining = float(cum[-1] - s_robot)
    speed = params.max_linear if current_speed is None else abs(current_speed)
    lookahead = min(params.max_lookahead, max(params.min_lookahead, speed * params.lookahead_time))
    target = _lookahead_point(pts, cum, xy, s_robot, lookahead)
    local = to_robot_frame(pose, target[None, :])[0]
    dist2 = float(local @ local)
    if dist2 < 1e-12:
        return (0.0, 0.0)
    heading_error = math.atan2(local[1], local[0])
    if abs(heading_error) > params.rotate_to_heading_angle:
        return (0.0, rotate_toward(heading_error, params))

    curvature = 2.0 * local[1] / dist2
    v = params.max_linear
    if abs(curvature) > 1e-9 and 1.0 / abs(curvature) < params.regulated_min_radius:
        v *= (1.0 / abs(curvature)) / params.regulated_min_radius
    if remaining < params.approach_distance:
        v = min(v, max(params.min_approach_linear, params.max_linear * remaining / params.approach_distance))
    if scan_points is not None and len(scan_points):
        near = to_robot_frame(pose, scan_points)
        horizon = remaining + params.obstacle_end_margin
        v *= obstacle_speed_scale(obstacle_clearance(near, curvature, params, horizon), params)
    omega = v * curvature
    if abs(omega) > params.max_angular:
        v *= params.max_angular / abs(omega)
        omega = math.copysign(params.max_angular, omega)
    return (float(v), float(omega))


def _lookahead_point(pts: np.ndarray, cum: np.ndarray, xy: np.ndarray, s_robot: float, lookahead: float) -> np.ndarray:
    """Where the path beyond the robot's projection first leaves the `lookahead` m circle, else the path end."""
    later = np.flatnonzero(cum > s_robot)
    if len(later) == 0:
        return pts[-1]
    cand = np.vstack([point_at(pts, s_robot, cum=cum)[None, :], pts[later]])
    d = np.hypot(*(cand - xy).T)
    beyond = np.flatnonzero(d >= lookahead)
    if len(beyond) == 0:
        return pts[-1]
    k = int(beyond[0])
    if k == 0:
        return cand[0]
    # intersection of the lookahead circle with the segment from cand[k-1] (inside) to cand[k] (outside)
    p0, d = cand[k - 1] - xy, cand[k] - cand[k - 1]
    a, b, c = float(d @ d), 2.0 * float(p0 @ d), float(p0 @ p0) - lookahead * lookahead
    t = (-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a) if a > 0.0 else 1.0
    return cand[k - 1] + min(max(t, 0.0), 1.0) * d
