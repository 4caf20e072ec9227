"""NavigateToPose: one navigation goal at a time with ROS actionlib / Nav2 semantics, stepped by the caller.

Owns: the goal life cycle (send, preempt, cancel, feedback, one result per goal), replanning, the
success, stuck and no-path rules. Must not know: the clock (every call takes `now`, simulated s),
bodies, MuJoCo, the protocol or which behaviour sent the goal.
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.nav import pursuit_kernels
from rescuemesh.nav.controller import ControllerParams, command_on_part, limit_acceleration, rotate_toward
from rescuemesh.nav.costmap import Costmap
from rescuemesh.nav.path import Path
from rescuemesh.nav.planner import Planner, make_planner


class GoalStatus(enum.Enum):
    """State of the action (actionlib_msgs/GoalStatus, reduced): IDLE before any goal."""

    IDLE = "idle"
    ACTIVE = "active"
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELED = "canceled"


class NavReason(enum.StrEnum):
    """Why a goal ended (the values are the words the logs show)."""

    REACHED = "reached"
    NO_PATH = "no path"
    STUCK = "stuck"
    CANCELED = "canceled"
    PREEMPTED = "preempted"


@dataclass(frozen=True)
class NavFeedback:
    """Progress of the active goal: remaining path length in m to the goal, at time `now` s."""

    goal_id: int
    distance_remaining_m: float
    now: float


@dataclass(frozen=True)
class NavResult:
    """How a goal ended, at time `now` s, and why."""

    goal_id: int
    status: GoalStatus
    reason: NavReason
    now: float


@dataclass(frozen=True)
class NavParams:
    """Goal checking, replanning and progress rules (TurtleBot 2 navigation defaults), and the controller's tuning."""

    xy_tolerance: float = 0.15  # m
    yaw_tolerance: float = 0.3  # rad
    replan_period_s: float = 1.0  # s between routine replans
    min_replan_interval_s: float = 0.25  # s: a path found blocked is replanned at most this often
    #: m: a goal moved (update_goal) at most this far from the path's end, with a free straight
    #: segment to it, extends the path instead of replanning it (a follower's leader moves a little
    #: per PoseUpdate); routine replans still come every replan_period_s.
    extend_max_m: float = 1.0
    stuck_timeout_s: float = 10.0  # s without progress -> ABORTED "stuck"
    progress_radius_m: float = 0.25  # m: moving this far counts as progress (Nav2 progress checker)
    progress_gain_m: float = 0.05  # m: getting this much closer to the goal counts as progress
    controller: ControllerParams = field(default_factory=ControllerParams)


@dataclass
class _Goal:
    """The running goal and everything learned while pursuing it."""

    goal_id: int
    pose: Pose2D
    stop_distance: float
    check_yaw: bool
    clear_radius: float
    path: Path | None = None
    s_progress: float = 0.0  # m along `path` the robot has reached
    last_plan: float = -math.inf
    force_replan: bool = True
    on_fallback: bool = False  # the path ignores scan obstacles: no path around them was found
    xy_reached: bool = False
    progress_at: float | None = None
    progress_xy: tuple[float, float] = (math.nan, math.nan)
    best_remaining: float = math.inf
    best_yaw_error: float = math.inf


class NavigateToPose:
    """Drive to one goal pose at a time; call `step(now, pose, scan)` every control tick (20 Hz).

    Life cycle: `send_goal` makes a goal ACTIVE (preempting a running one, which ends CANCELED
    "preempted"); `cancel` ends it CANCELED "canceled"; `step` plans on the first tick and every
    `replan_period_s` (sooner when scan obstacles block the path), ends it SUCCEEDED "reached",
    ABORTED "no path" (none even ignoring scan obstacles) or ABORTED "stuck" (no progress for
    `stuck_timeout_s`). Each goal yields exactly one NavResult through `next_result()`. `status` is
    the latest goal's state (IDLE before the first goal).

    A plain goal succeeds within `xy_tolerance` of the goal (latched, as Nav2's stateful goal
    checker), then, when `check_yaw`, after rotating in place to within `yaw_tolerance`. A goal with
    `stop_distance` > 0 succeeds when the remaining path is at most `stop_distance` m (yaw ignored);
    the controller is handed the path cut short by that much, so it slows down to stop there.
    """

    def __init__(self, costmap: Costmap, *, planner: str | Planner = "mcp", params: NavParams = NavParams()) -> None:
        """`costmap`: the static costmap (scan obstacles are layered on per sweep).

        `planner`: a name registered in PLANNERS, or a Planner instance.
        """
        self.costmap = costmap
        self.params = params
        self.planner = make_planner(planner) if isinstance(planner, str) else planner
        self._status = GoalStatus.IDLE
        self._goal: _Goal | None = None
        self._next_id = 1
        self._results: deque[NavResult] = deque()
        self._feedback: NavFeedback | None = None
        self._scan_points = np.zeros((0, 2))
        self._scan_stamp: float | None = None
        self._obstacle_costmap: Costmap | None = None
        self._last_v = 0.0
        self._last_step: float | None = None

    # -- public state ---------------------------------------------------------------------------

    @property
    def status(self) -> GoalStatus:
        return self._status

    @property
    def feedback(self) -> NavFeedback | None:
        """Latest feedback of the active goal; None when no goal is active or before its first step."""
        return self._feedback

    @property
    def path(self) -> Path | None:
        """The active goal's current planned path (map frame), or None."""
        return self._goal.path if self._goal is not None else None

    @property
    def goal(self) -> Pose2D | None:
        """The active goal's pose, or None."""
        return self._goal.pose if self._goal is not None else None

    @property
    def goal_id(self) -> int | None:
        """The active goal's id, or None."""
        return self._goal.goal_id if self._goal is not None else None

    def next_result(self) -> NavResult | None:
        """The oldest result not yet taken, or None."""
        return self._results.popleft() if self._results else None

    # -- requests -------------------------------------------------------------------------------

    def send_goal(
        self, goal: Pose2D, now: float, *, stop_distance: float = 0.0, check_yaw: bool = True, clear_radius: float = 0.0
    ) -> int:
        """Start a goal (map frame); returns its id. A running goal ends CANCELED "preempted".

        `stop_distance` m > 0: succeed when the remaining path is at most that long (follow a leader;
        yaw not checked). `clear_radius` m > 0: plan as if no scan obstacle were within that radius of
        the goal, and accept the nearest free cell within it when the goal itself is in lethal space;
        the controller still stops for every scan point (the follower never rams its leader).
        """
        if self._goal is not None:
            self._finish(GoalStatus.CANCELED, NavReason.PREEMPTED, now)
        goal_id = self._next_id
        self._next_id += 1
        self._goal = _Goal(
            goal_id, goal, max(0.0, stop_distance), check_yaw and stop_distance <= 0.0, max(0.0, clear_radius)
        )
        self._obstacle_costmap = None
        self._status = GoalStatus.ACTIVE
        return goal_id

    def update_goal(self, goal: Pose2D, now: float) -> bool:
        """Move the active goal to `goal` without preempting it (Nav2's goal updater, for following).

        Keeps the id and options. A goal moved at most `extend_max_m` from the path's end, reachable
        from it in a straight line on the static costmap, extends the path by that segment; any other
        move replans on the next step. False (and no effect) when idle.
        """
        g = self._goal
        if g is None:
            return False
        extended = self._extended(g.path, goal)
        g.pose, g.xy_reached, g.best_remaining = goal, False, math.inf
        if extended is None:
            g.path, g.s_progress = None, 0.0
        else:
            g.path = extended  # the same points up to the old end: s_progress still holds
        self._obstacle_costmap = None
        return True

    def _extended(self, path: Path | None, goal: Pose2D) -> Path | None:
        """`path` with a straight segment on to `goal`, when the goal is within extend_max_m of its end
        and the segment crosses no lethal cell of the static costmap; else None."""
        if path is None:
            return None
        end = path.end
        gap = math.hypot(goal.x - end[0], goal.y - end[1])
        if gap > self.params.extend_max_m:
            return None
        if gap < 1e-6:
            return path
        n = max(2, math.ceil(gap / (0.5 * self.costmap.resolution)) + 1)
        if self.costmap.segment_any_lethal((end[0], end[1]), (goal.x, goal.y), n):  # every half cell
            return None
        return path.extended_to(goal.x, goal.y)  # Path.from_points(np.vstack([path.points, [[goal.x, goal.y]]]))

    def cancel(self, now: float) -> None:
        """End the active goal CANCELED "canceled"; no-op when idle."""
        if self._goal is not None:
            self._finish(GoalStatus.CANCELED, NavReason.CANCELED, now)

    # -- the tick -------------------------------------------------------------------------------

    def step(self, now: float, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float]:
        """Advance the active goal at `now` s from `pose` (map frame); returns (v m/s, omega rad/s).

        (0, 0) when no goal is active. `scan` is read once per sweep (by its stamp); None keeps the
        last sweep's points (none before the first).
        """
        dt = 0.0 if self._last_step is None else max(0.0, now - self._last_step)
        self._last_step = now
        self._take_scan(scan)
        g = self._goal
        if g is None:
            self._last_v = 0.0
            return (0.0, 0.0)
        if g.progress_at is None:
            g.progress_at, g.progress_xy = now, (pose.x, pose.y)
        v, omega = self._step_goal(g, now, pose)
        v = limit_acceleration(v, self._last_v, dt, self.params.controller)
        self._last_v = v
        return (v, omega)

    def _step_goal(self, g: _Goal, now: float, pose: Pose2D) -> tuple[float, float]:
        p = self.params
        if g.stop_distance <= 0.0 and not g.xy_reached:
            g.xy_reached = self._within_xy(g, pose)
        if g.xy_reached:
            return self._align(g, now, pose)

        if self._replan_due(g, now, pose) and not self._replan(g, now, pose):
            return (0.0, 0.0)
        path = g.path
        assert path is not None
        points, cum = np.ascontiguousarray(path.points, dtype=float), path.cum
        window = g.s_progress + p.controller.path_search_distance
        # Polyline.project(pose, s_min=s_progress, s_max=window), compiled
        g.s_progress = pursuit_kernels.project(points, cum, pose.x, pose.y, g.s_progress, window)
        ex, ey = points[-1].tolist()
        goal_gap = math.hypot(ex - g.pose.x, ey - g.pose.y)
        remaining = max(0.0, path.length_m - g.s_progress) + goal_gap
        self._feedback = NavFeedback(g.goal_id, remaining, now)

        if g.stop_distance > 0.0 and remaining <= g.stop_distance:
            self._finish(GoalStatus.SUCCEEDED, NavReason.REACHED, now)
            return (0.0, 0.0)
        if g.stop_distance <= 0.0 and self._within_xy(g, pose):
            g.xy_reached = True
            return self._align(g, now, pose)
        if self._stuck(g, now, pose, remaining, None):
            return (0.0, 0.0)

        s_end = path.length_m
        if g.stop_distance > 0.0:
            s_end = path.length_m + goal_gap - g.stop_distance
        # compute_velocity on the path's part ahead (Polyline.slice(s_progress, s_end)): one compiled call
        return command_on_part(pose, points, cum, g.s_progress, s_end, self._scan_points, p.controller, self._last_v)

    # -- helpers --------------------------------------------------------------------------------

    def _within_xy(self, g: _Goal, pose: Pose2D) -> bool:
        tol = self.params.xy_tolerance
        if pose.distance_to(g.pose) <= tol:
            return True
        # a goal in lethal space accepted via clear_radius is reached at the free cell the path ends in
        if g.path is None:
            return False
        ex, ey = g.path.points[-1].tolist()
        snapped = math.hypot(ex - g.pose.x, ey - g.pose.y) > 1e-6
        return snapped and math.hypot(ex - pose.x, ey - pose.y) <= tol

    def _align(self, g: _Goal, now: float, pose: Pose2D) -> tuple[float, float]:
        self._feedback = NavFeedback(g.goal_id, pose.distance_to(g.pose), now)
        if not g.check_yaw:
            self._finish(GoalStatus.SUCCEEDED, NavReason.REACHED, now)
            return (0.0, 0.0)
        error = wrap_angle(g.pose.yaw - pose.yaw)
        if abs(error) <= self.params.yaw_tolerance:
            self._finish(GoalStatus.SUCCEEDED, NavReason.REACHED, now)
            return (0.0, 0.0)
        if self._stuck(g, now, pose, None, abs(error)):
            return (0.0, 0.0)
        return (0.0, rotate_toward(error, self.params.controller))

    def _stuck(self, g: _Goal, now: float, pose: Pose2D, remaining: float | None, yaw_error: float | None) -> bool:
        """Track progress; end the goal ABORTED "stuck" after `stuck_timeout_s` without any."""
        p = self.params
        progressed = math.hypot(pose.x - g.progress_xy[0], pose.y - g.progress_xy[1]) >= p.progress_radius_m
        if remaining is not None and remaining <= g.best_remaining - p.progress_gain_m:
            g.best_remaining, progressed = remaining, True
        if yaw_error is not None and yaw_error <= g.best_yaw_error - 0.05:
            g.best_yaw_error, progressed = yaw_error, True
        if progressed:
            g.progress_at, g.progress_xy = now, (pose.x, pose.y)
            return False
        assert g.progress_at is not None
        if now - g.progress_at > p.stuck_timeout_s:
            self._finish(GoalStatus.ABORTED, NavReason.STUCK, now)
            return True
        return False

    def _take_scan(self, scan: LaserScan | None) -> None:
        if scan is None:
            return
        if self._scan_stamp != scan.stamp:
            self._scan_stamp = scan.stamp
            self._scan_points = scan.points_in_map()
            self._obstacle_costmap = None

    def _costmap_for(self, g: _Goal) -> Costmap:
        """The static costmap plus the latest scan, cleared within clear_radius of the goal (cached per scan)."""
        if self._obstacle_costmap is None:
            self._obstacle_costmap = self.costmap.with_obstacles(
                self._scan_points, self._scan_stamp, clear_center=(g.pose.x, g.pose.y), clear_radius=g.clear_radius
            )
        return self._obstacle_costmap

    def _replan_due(self, g: _Goal, now: float, pose: Pose2D) -> bool:
        if g.path is None or g.force_replan:
            return True
        since = now - g.last_plan
        if since >= self.params.replan_period_s:
            return True
        if g.on_fallback or since < self.params.min_replan_interval_s or len(self._scan_points) == 0:
            return False
        return self._blocked(g)

    def _blocked(self, g: _Goal) -> bool:
        """True when the path ahead (beyond the robot's footprint, outside clear_radius) crosses a lethal cell."""
        assert g.path is not None
        cm = self._costmap_for(g)
        s0 = g.s_progress + self.params.controller.footprint_radius + 0.1
        if s0 >= g.path.length_m:
            return False
        # samples every cell along the path (clamped to its ends as point_at is), tested in one compiled call
        return cm.any_lethal_along(g.path.points, g.path.cum, s0, g.path.length_m, cm.resolution,
                                   clear_center=(g.pose.x, g.pose.y), clear_radius=g.clear_radius)

    def _replan(self, g: _Goal, now: float, pose: Pose2D) -> bool:
        """Plan from `pose`; False (goal ABORTED "no path") when there is none even without scan obstacles."""
        cm = self._costmap_for(g)
        path = self.planner.plan(cm, pose, g.pose, goal_tolerance=g.clear_radius)
        fallback = False
        if path is None and len(cm.obstacle_points):
            # scan obstacles (a robot in a doorway) close every way: keep going on the static map,
            # the controller stops short of them and the stuck timer decides
            path = self.planner.plan(self.costmap, pose, g.pose, goal_tolerance=g.clear_radius)
            fallback = True
        if path is None:
            self._finish(GoalStatus.ABORTED, NavReason.NO_PATH, now)
            return False
        g.path, g.s_progress, g.last_plan, g.force_replan, g.on_fallback = path, 0.0, now, False, fallback
        return True

    def _finish(self, status: GoalStatus, reason: NavReason, now: float) -> None:
        g = self._goal
        assert g is not None
        self._results.append(NavResult(g.goal_id, status, reason, now))
        self._status = status
        self._goal = None
        self._feedback = None
