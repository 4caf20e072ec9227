"""Behaviours a robot runs: navigate to its own goal, follow a leader, move around a centre.

Owns: each behaviour's state and its use of NavigateToPose. Must not know: the protocol wire,
the simulator, who commanded the behaviour (the brain keeps that).
A behaviour is stepped with (now, pose, scan) and returns a body twist (v in m/s, omega in rad/s);
it can be paused (halted, its goal cancelled) and resumed when a partner's link drops and returns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, yaw_to_quaternion
from rescuemesh.nav import GoalStatus, NavigateToPose, NavReason
from rescuemesh.protocol import Reason, ResultCode

STOPPED = (0.0, 0.0)


class Behaviour:
    """Base: `step` until `outcome` is set to DONE or FAILED (with a `reason` code and a `detail`)."""

    name = "behaviour"

    def __init__(self, nav: NavigateToPose) -> None:
        self.nav = nav
        self.outcome: ResultCode | None = None
        self.reason = Reason.NONE
        self.detail = ""
        self.paused = False
        self._my_goal_id: int | None = None

    @property
    def finished(self) -> bool:
        return self.outcome is not None

    def pause(self, now: float) -> None:
        """Halt and wait (the partner's link is lost): cancel the goal; `step` returns STOPPED."""
        if not self.paused:
            self.paused = True
            self.halt(now)

    def resume(self, now: float) -> None:
        """Carry on after a pause: send the goal again."""
        if self.paused:
            self.paused = False
            self._restart(now)

    def _restart(self, now: float) -> None:
        """Send the navigation goal again after a pause (each behaviour knows its goal)."""

    def progress(self) -> int:
        """Percent done, 255 when unknown (MAVLink COMMAND_ACK convention)."""
        return 255

    def step(self, now: float, pose: Pose2D, scan: LaserScan | None) -> tuple[float, float]:
        raise NotImplementedError

    def halt(self, now: float) -> None:
        """Stop driving: cancel the navigation goal, if it is still this behaviour's (a behaviour
        that replaces this one may have sent its own already)."""
        if self.nav.goal_id is not None and self.nav.goal_id == self._my_goal_id:
            self.nav.cancel(now)

    def _send_nav_goal(self, goal: Pose2D, now: float, **options) -> int:
        self._my_goal_id = self.nav.send_goal(goal, now, **options)
        return self._my_goal_id

    def _finish(self, outcome: ResultCode, reason: Reason = Reason.NONE, detail: str = "") -> tuple[float, float]:
        self.outcome, self.reason, self.detail = outcome, reason, detail
        return STOPPED


class NavigateBehaviour(Behaviour):
    """Drive to one goal (a robot's own mission, or a Goto later)."""

    name = "navigate"

    def __init__(self, nav: NavigateToPose, goal: Pose2D, now: float) -> None:
        super().__init__(nav)
        self.goal = goal
        self.goal_id = self._send_nav_goal(goal, now)
        self._total_m: float | None = None  # the first remaining distance the navigator reports

    def _restart(self, now: float) -> None:
        self.goal_id = self._send_nav_goal(self.goal, now)

    def progress(self) -> int:
        """Percent of the path driven (0..99 while driving), from NavigateToPose feedback."""
        feedback = self.nav.feedback
        if feedback is None or feedback.goal_id != self.goal_id:
            return 255 if self._total_m is None else 0
        if self._total_m is None or feedback.distance_remaining_m > self._total_m:
            self._total_m = max(feedback.distance_remaining_m, 1e-6)
        return max(0, min(99, int(100 * (1 - feedback.distance_remaining_m / self._total_m))))

    def step(self, now, pose, scan):
        if self.paused:
            return STOPPED
        v_w = self.nav.step(now, pose, scan)
        while (result := self.nav.next_result()) is not None:
            if result.goal_id != self.goal_id:
                continue
            if result.status is GoalStatus.SUCCEEDED:
                return self._finish(ResultCode.DONE)
            reason = Reason.NO_PATH if result.reason is NavReason.NO_PATH else Reason.STUCK
            return self._finish(ResultCode.FAILED, reason, f"navigation {result.status.name.lower()}: {result.reason}")
        return v_w


class FollowBehaviour(Behaviour):
    """Follow a leader: drive toward where it is now, stop `distance_m` short along the path.

    PoseUpdates come at 2 Hz; between them the leader's position is predicted from its velocity
    over the last two updates, at most `predict_horizon_s` ahead, so the follower moves smoothly
    instead of lurching at each update. When no PoseUpdate has come for `partner_timeout_s` the
    robot halts and waits (a robot that loses its partner stops safely); the next PoseUpdate sets
    it going again. After `partner_give_up_s` of silence the Follow ends FAILED (PARTNER_SILENT):
    normally the brain's link-loss rule (heartbeats) ends it first, with LINK_LOST.
    """

    name = "follow"

    def __init__(self, nav, leader: int, target: Pose2D, now: float, *, distance_m: float,
                 partner_timeout_s: float, partner_give_up_s: float, regoal_shift_m: float = 0.1,
                 clear_radius_m: float = 0.5, predict_horizon_s: float = 1.0) -> None:
        super().__init__(nav)
        self.leader = leader
        self.partner_give_up_s = partner_give_up_s
        self.holding = False  # halted because the leader went silent
        self.predict_horizon_s = predict_horizon_s
        self.velocity = (0.0, 0.0)  # leader's estimated velocity in the map frame, m/s
        self.distance_m = distance_m
        self.partner_timeout_s = partner_timeout_s
        self.regoal_shift_m = regoal_shift_m
        self.clear_radius_m = clear_radius_m
        self.target = target
        self.last_heard = now
        self._goal_target: Pose2D | None = None
        self._send_goal(now)

    def on_pose_update(self, pose: Pose2D, now: float) -> None:
        dt = now - self.last_heard
        if dt > 0.05:
            self.velocity = ((pose.x - self.target.x) / dt, (pose.y - self.target.y) / dt)
        self.target = pose
        self.last_heard = now
        self.holding = False
        if self.nav.status is not GoalStatus.ACTIVE and not self.paused:
            self._send_goal(now)

    def _restart(self, now: float) -> None:
        if not self.holding:
            self._send_goal(now)

    def predicted_target(self, now: float) -> Pose2D:
        """Where the leader should be at `now`, from its last pose and velocity (map frame)."""
        ahead = min(max(0.0, now - self.last_heard), self.predict_horizon_s)
        return Pose2D(self.target.x + self.velocity[0] * ahead, self.target.y + self.velocity[1] * ahead,
                      self.target.yaw)

    def _track(self, now: float) -> None:
        target = self.predicted_target(now)
        if self.nav.status is not GoalStatus.ACTIVE:
            return
        if self._goal_target is None or self._goal_target.distance_to(target) > self.regoal_shift_m:
            self._goal_target = target
            self.nav.update_goal(target, now)  # move the goal without preempting it (Nav2's goal updater)

    def _send_goal(self, now: float) -> None:
        self._goal_target = self.target
        self._send_nav_goal(self.target, now, stop_distance=self.distance_m, check_yaw=False,
                            clear_radius=self.clear_radius_m)

    def step(self, now, pose, scan):
        silent = now - self.last_heard
        if silent > self.partner_give_up_s:
            self.halt(now)
            return self._finish(ResultCode.FAILED, Reason.PARTNER_SILENT, f"leader silent for {silent:.1f} s")
        if self.paused:
            return STOPPED
        if silent > self.partner_timeout_s:
            if not self.holding:
                self.holding = True
                self.halt(now)
            return STOPPED
        self._track(now)
        v_w = self.nav.step(now, pose, scan)
        while self.nav.next_result() is not None:
            pass  # preempted, reached (within distance) or aborted: the next PoseUpdate sets a new goal
        return v_w


@dataclass(frozen=True)
class Waypoint:
    """A MoveAround waypoint: the pose, and its heading as a quaternion (x, y, z, w) for a ROS goal."""

    index: int
    pose: Pose2D
    quaternion: tuple[float, float, float, float] = field(compare=False)


def circle_waypoints(center: Pose2D, radius_m: float, count: int, start_near: Pose2D) -> list[Waypoint]:
    """`count` waypoints evenly spaced in angle on the circle, anticlockwise, tangent heading.

    The first is the one nearest `start_near`; the list closes the circle by ending on it again,
    so `count + 1` poses come back. (The paper divides the x axis into 20 steps and solves for y,
    which bunches points at the circle's sides; equal angles space them evenly.)
    """
    step = 2.0 * math.pi / count
    start_angle = math.atan2(start_near.y - center.y, start_near.x - center.x)
    first = round(start_angle / step) % count
    points = []
    for k in range(count + 1):
        index = (first + k) % count
        angle = index * step
        heading = angle + math.pi / 2.0
        pose = Pose2D(center.x + radius_m * math.cos(angle), center.y + radius_m * math.sin(angle), heading)
        points.append(Waypoint(index, pose, yaw_to_quaternion(heading)))
    return points


#: A circle counts as done when at least this share of its (free) waypoints was reached.
MIN_WAYPOINTS_REACHED = 0.9


class MoveAroundBehaviour(Behaviour):
    """Circle a centre anticlockwise through evenly spaced waypoints; skip those inside obstacles."""

    name = "move-around"

    def __init__(self, nav, waypoints: list[Waypoint], skipped: list[Waypoint], now: float,
                 *, pass_radius_m: float = 0.3) -> None:
        super().__init__(nav)
        self.waypoints = waypoints
        self.skipped = list(skipped)
        self.pass_radius_m = pass_radius_m
        self.current = 0
        self.unreached: list[Waypoint] = []
        self._goal_id = self._send(now)

    def progress(self) -> int:
        return int(100 * self.current / max(1, len(self.waypoints)))

    def _send(self, now: float) -> int:
        return self._send_nav_goal(self.waypoints[self.current].pose, now, check_yaw=False)

    def _restart(self, now: float) -> None:
        self._goal_id = self._send(now)

    def _verdict(self) -> tuple[float, float]:
        """DONE only if the circle was really driven: most waypoints reached, not merely tried."""
        total = len(self.waypoints)
        reached = total - len(self.unreached)
        if reached == 0:
            return self._finish(ResultCode.FAILED, Reason.BLOCKED, "no waypoint reachable")
        if reached < MIN_WAYPOINTS_REACHED * total:
            return self._finish(ResultCode.FAILED, Reason.STUCK, f"reached {reached} of {total} waypoints")
        return self._finish(ResultCode.DONE)

    def _advance(self, now: float) -> bool:
        self.current += 1
        if self.current >= len(self.waypoints):
            return False
        self._goal_id = self._send(now)
        return True

    def step(self, now, pose, scan):
        if self.paused:
            return STOPPED
        last = self.current == len(self.waypoints) - 1
        if not last and pose.distance_to(self.waypoints[self.current].pose) < self.pass_radius_m:
            self._advance(now)  # pass through intermediate waypoints without stopping
        v_w = self.nav.step(now, pose, scan)
        while (result := self.nav.next_result()) is not None:
            if result.goal_id != self._goal_id:
                continue
            if result.status is GoalStatus.ABORTED:
                self.unreached.append(self.waypoints[self.current])
            if not self._advance(now):
                return self._verdict()
            v_w = STOPPED
        return v_w
