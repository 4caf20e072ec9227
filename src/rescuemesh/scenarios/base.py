"""What a scenario is: options, start poses, a mission script stepped with the runtime, and a verdict.

Owns: ScenarioOptions, ScenarioError, the Scenario base class and the command-retry helper that
mission scripts share. Must not know: how results are written or plotted, the command line.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from rescuemesh.body import RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import RobotBrain, robot_address
from rescuemesh.runtime import RadioKind, SimConfig

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime, TrajectorySample

ROBOTS = ("robot_1", "robot_2", "robot_3")
#: Name of the packaged office map (rescuemesh/data/office.yaml): scenarios have default poses for it.
OFFICE_MAP_NAME = "small_office"
#: Two TurtleBot 2 footprints (0.177 m radius each) plus a little room.
MIN_START_SEPARATION_M = 0.4
#: A robot with no task, placed automatically, starts at least this far (m) from every other robot.
IDLE_SEPARATION_M = 1.5
#: Lattice points looked at beyond the team's size when placing idle robots.
IDLE_SPARE_CANDIDATES = 12
#: Room a ground robot needs around its start: the TurtleBot 2 footprint (0.177 m radius, as
#: sim/mjcf.py CHASSIS_RADIUS) and a few mm. Every grid cell nearer than this must be free.
START_CLEARANCE_M = 0.18


class ScenarioError(ValueError):
    """Options a scenario cannot run with; the message is one line for the user."""


@dataclass(frozen=True)
class ScenarioOptions:
    """What a user may set for a run (the CLI's flags)."""

    seed: int = 0
    loss: float = 0.0
    radius_m: float = 1.5
    starts: dict[str, Pose2D] = field(default_factory=dict)
    goal: Pose2D | None = None
    time_limit_s: float | None = None
    radio: RadioKind = RadioKind.BLE
    relay: bool = True
    outage_s: float | None = None  # disconnect: how long robot_1's radio is silent
    robots: int | None = None  # --robots: team size, for scenarios that take one (None: the scenario's default)
    secure: bool = True  # authenticated frames (False: --insecure, CRC only)
    team_key: bytes | None = None  # --key FILE; None: derived from the seed (simulation only)
    key_source: str = "derived from the seed (simulation only)"


@dataclass
class Verdict:
    """A scenario's outcome: success, the criteria checked (text, held), and its own metrics."""

    success: bool
    criteria: list[tuple[str, bool]]
    metrics: dict


class CommandRequest:
    """Send a command until one copy is confirmed, at most `attempts` commands.

    The protocol already resends each frame (3 sends); this is the mission's retry on top: when
    the protocol gives a command up, the brain sends Stop to the peer, and once nothing to that
    peer is pending any more the mission asks again.
    """

    def __init__(self, brain: RobotBrain, peer: str, send, *, attempts: int = 3) -> None:
        self.brain, self.peer, self._send = brain, robot_address(peer), send
        self.attempts, self.seqs = attempts, []

    def poll(self, now: float) -> ResultCode | None:
        """The result of the first confirmed copy, or None while waiting. Sends as needed."""
        for seq in self.seqs:
            sent = self.brain.outgoing[seq]
            if sent.result is not None and not sent.failed:
                return sent.result
        pending = any(not c.failed and c.result is None for c in self.brain.outgoing.values() if c.peer == self.peer)
        if not pending and len(self.seqs) < self.attempts:
            self.seqs.append(self._send(self.peer, now))
        return None

    def confirmed(self):
        """The first copy that got an answer (its OutgoingCommand, with the latest result), or None."""
        outgoing = self.brain.outgoing
        return next((outgoing[s] for s in self.seqs if outgoing[s].result is not None and not outgoing[s].failed),
                    None)

    @property
    def given_up(self) -> bool:
        return len(self.seqs) >= self.attempts and all(self.brain.outgoing[s].failed for s in self.seqs)


class Scenario(abc.ABC):
    """One scenario: robots, a mission script, success criteria and metrics."""

    name: ClassVar[str]
    summary: ClassVar[str]
    time_limit_s: ClassVar[float]

    #: Whether --outage means anything to this scenario.
    takes_outage: ClassVar[bool] = False
    #: Whether --goal means anything to this scenario (a leader's goal, a Goto pose, a spot to show).
    takes_goal: ClassVar[bool] = False
    #: Whether --robots N means anything to this scenario (it then sets `robots` from it).
    takes_team_size: ClassVar[bool] = False
    #: Whether the scenario runs with each robot in its own process (--processes): its script and
    #: criteria only read and call brains, never the robots' internals in place.
    runs_as_processes: ClassVar[bool] = False
    #: Robots with no task in this scenario: on a map with no start for one, it is placed
    #: automatically (behind robot_1, away from the mission point, clear of the other starts).
    idle_robots: ClassVar[tuple[str, ...]] = ("robot_3",)
    #: What the `goal` of this scenario's metrics is, for the star in trajectory.png.
    goal_label: ClassVar[str] = "leader's goal"
    #: The team of this scenario.
    robots: ClassVar[tuple[str, ...]] = ROBOTS
    #: Robots this scenario adds to the map's starts on the packaged office: name -> (pose, what
    #: the robot is); on any other map each needs a --start.
    office_extra_starts: ClassVar[dict[str, tuple[Pose2D, str]]] = {}

    def __init__(self, options: ScenarioOptions, map_model: MapModel) -> None:
        self.options = options
        self._checked_starts: dict[str, Pose2D] | None = None
        self.map = map_model
        if options.outage_s is not None and not self.takes_outage:
            raise ScenarioError(f"--outage applies to the disconnect scenario, not to {self.name}")
        if options.goal is not None and not self.takes_goal:
            raise ScenarioError(f"--goal applies to follow, stop, disconnect, spoof, convoy, goto, return, show-scan "
                                f"and show-cam, not to {self.name}")
        if options.robots is not None and not self.takes_team_size:
            raise ScenarioError(f"--robots applies to the convoy scenario, not to {self.name} (its team is "
                                f"{', '.join(self.robots)})")
        self.validate()

    @property
    def limit_s(self) -> float:
        return self.options.time_limit_s or self.time_limit_s

    def validate(self) -> None:
        """Raise ScenarioError for options this scenario cannot run with."""

    def sim_config(self) -> SimConfig:
        """How the runtime is set up for this scenario (a scenario may override parts)."""
        o = self.options
        return SimConfig(seed=o.seed, loss=o.loss, radio=o.radio, relay=o.relay, secure=o.secure, team_key=o.team_key)

    @property
    def on_office(self) -> bool:
        """Whether this run is on the packaged office, where the scenario's default poses apply."""
        return self.map.name == OFFICE_MAP_NAME

    def require_free(self, what: str, point: Pose2D) -> None:
        """ScenarioError when `point` (described as `what`) lies in an obstacle or off the map."""
        if self.map.grid.is_occupied(point.x, point.y):
            raise ScenarioError(f"{what} ({point.x:.2f}, {point.y:.2f}) is inside an obstacle or off the map")

    def default_starts(self) -> dict[str, Pose2D]:
        """Start poses before --start: the map's, plus `office_extra_starts` on the office (a scenario
        may place its robots itself)."""
        starts = dict(self.map.starts)
        for name, (pose, role) in self.office_extra_starts.items():
            if self.on_office:
                starts[name] = pose
            elif name not in self.options.starts:
                raise ScenarioError(f"{self.name} needs --start {name}=X,Y,YAW ({role}) on map {self.map.name!r}")
        return starts

    def starts(self) -> dict[str, Pose2D]:
        """Start poses: the defaults, overridden by --start; checked once (30 robots' clearances
        take 0.1 s), a new dict each call."""
        if self._checked_starts is None:
            self._checked_starts = self._check_starts()
        return dict(self._checked_starts)

    def _check_starts(self) -> dict[str, Pose2D]:
        robots = self.robots
        starts = {name: pose for name, pose in self.default_starts().items() if name in robots}
        for name in self.options.starts:
            robot_address(name)  # ValueError for a malformed robot name
            if name not in robots:
                raise ScenarioError(f"unknown robot {name!r}: this scenario has {', '.join(robots)}")
        starts.update(self.options.starts)
        idle = [name for name in robots if name not in starts and name in self.idle_robots]
        if idle and all(name in starts or name in idle for name in robots):
            starts.update(self._place_idle(starts, idle))
        missing = [name for name in robots if name not in starts]
        if missing:
            raise ScenarioError(f"map {self.map.name!r} has no start pose for {', '.join(missing)}: "
                                f"give --start NAME=X,Y,YAW")
        placed = list(starts.items())
        for i, (name, pose) in enumerate(placed):
            for other, other_pose in placed[i + 1:]:
                if pose.distance_to(other_pose) < MIN_START_SEPARATION_M:
                    raise ScenarioError(f"{name} and {other} start {pose.distance_to(other_pose):.2f} m apart: "
                                        f"robots need at least {MIN_START_SEPARATION_M} m")
        kinds = self.sim_config().kinds
        for name, pose in starts.items():
            self.require_free(f"start of {name}", pose)
            if kinds.get(name, RobotKind.GROUND) is not RobotKind.GROUND:
                continue  # a drone: its own body, only the centre is checked
            clearance = _clearance(self.map.grid, pose.x, pose.y, START_CLEARANCE_M)
            if clearance < START_CLEARANCE_M - 1e-9:
                raise ScenarioError(f"start of {name} ({pose.x:.2f}, {pose.y:.2f}) is {clearance:.2f} m from an "
                                    f"obstacle: a TurtleBot 2 needs {START_CLEARANCE_M:.2f} m")
        return starts

    def mission_point(self) -> Pose2D | None:
        """Where this scenario's mission heads (a goal, a spot to show): idle robots are placed away
        from it. None: away from robot_1 only."""
        return None

    def _place_idle(self, starts: dict[str, Pose2D], idle: list[str]) -> dict[str, Pose2D]:
        """Start poses for robots with no task and no start: lattice points behind robot_1 as the
        convoy places its team (scenarios/team.py), at least IDLE_SEPARATION_M from every start."""
        from rescuemesh.scenarios.team import PlacementError, place_behind

        leader = starts.get("robot_1") or next(iter(starts.values()))
        point = self.mission_point() or leader
        try:
            candidates = place_behind(self.map.grid, leader, (point.x, point.y),
                                      len(starts) + len(idle) + IDLE_SPARE_CANDIDATES)[1:]
        except PlacementError:
            candidates = []
        placed: dict[str, Pose2D] = {}
        taken = list(starts.values()) + list(self.map.bases.values())
        for pose in candidates:
            if len(placed) == len(idle):
                break
            if all(pose.distance_to(other) >= IDLE_SEPARATION_M for other in taken):
                placed[idle[len(placed)]] = pose
                taken.append(pose)
        if len(placed) < len(idle):
            names = ", ".join(name for name in idle if name not in placed)
            raise ScenarioError(f"map {self.map.name!r}: no room found for {names} (no task here) behind robot_1: "
                                f"give --start NAME=X,Y,YAW")
        return placed

    def write_files(self, rt: SimRuntime, out_dir) -> list:
        """Files of the scenario's own beside result.json and the plots (received scans, images)."""
        return []

    @abc.abstractmethod
    def tick(self, rt: SimRuntime) -> None:
        """The mission script, run after every control step."""

    @abc.abstractmethod
    def finished(self, rt: SimRuntime) -> bool:
        """True when the scenario has played out (before its time limit)."""

    @abc.abstractmethod
    def evaluate(self, rt: SimRuntime) -> Verdict:
        """Success criteria and the scenario's metrics."""


def _clearance(grid, x: float, y: float, reach: float) -> float:
    """Distance in m from (x, y) to the nearest obstacle or off-map cell (to the nearest point of
    that cell's square), looking `reach` m around; `reach` when there is none that near."""
    res = grid.resolution
    row, col = grid.world_to_cell(x, y)
    n = math.ceil(reach / res) + 1
    rows = np.arange(row - n, row + n + 1)
    cols = np.arange(col - n, col + n + 1)
    n_rows, n_cols = grid.shape
    r, c = np.meshgrid(rows, cols, indexing="ij")
    inside = (r >= 0) & (r < n_rows) & (c >= 0) & (c < n_cols)
    blocked = ~inside
    blocked[inside] = grid.occupied[r[inside], c[inside]]
    x_lo, y_lo = grid.origin_x + cols * res, grid.origin_y + rows * res  # lower-left corners
    dx = np.maximum(np.maximum(x_lo - x, x - (x_lo + res)), 0.0)
    dy = np.maximum(np.maximum(y_lo - y, y - (y_lo + res)), 0.0)
    distance = np.hypot(dy[:, None], dx[None, :])[blocked]
    return float(min(reach, distance.min())) if distance.size else reach


#: A robot counts as settled once its speed stays below SETTLED_SPEED (m/s) for SETTLE_S seconds.
SETTLED_SPEED = 0.03
SETTLE_S = 1.5


def settled(rt: SimRuntime, name: str, since_s: float) -> bool:
    """Whether robot `name` has been still for SETTLE_S s, counted from `since_s` at the earliest."""
    now = rt.time
    if now - since_s < SETTLE_S:
        return False
    for sample in reversed(rt.trajectories[name]):  # newest first: only the last SETTLE_S s matter
        if sample.time_s < now - SETTLE_S:
            return True
        if sample.speed >= SETTLED_SPEED:
            return False
    return True


def no_collisions(rt: SimRuntime) -> tuple[str, bool]:
    total = sum(rt.world.collisions.values())
    return (f"no collision ({total} seen)", total == 0)


def mean_distance(a: list[TrajectorySample], b: list[TrajectorySample], t0: float, t1: float) -> float:
    """Mean centre-to-centre distance in m between two robots' recorded positions (one sample per
    control step) over [t0, t1] s."""
    pairs = [(p.pose, q.pose) for p, q in zip(a, b) if t0 <= p.time_s <= t1]
    if not pairs:
        return math.nan
    return sum(p.distance_to(q) for p, q in pairs) / len(pairs)


def following_error(a: list[TrajectorySample], b: list[TrajectorySample], t0: float, t1: float,
                    set_distance_m: float) -> dict | None:
    """How far follower `b` kept from leader `a` against the set following distance, over the
    samples in [t0, t1] s: centre-to-centre distance minus `set_distance_m`, as its mean (signed:
    positive is lagging), RMS and largest value, in m; None with no sample in the window."""
    errors = [p.pose.distance_to(q.pose) - set_distance_m for p, q in zip(a, b) if t0 <= p.time_s <= t1]
    if not errors:
        return None
    return {"set_distance_m": set_distance_m, "mean_m": round(sum(errors) / len(errors), 3),
            "rms_m": round(math.sqrt(sum(e * e for e in errors) / len(errors)), 3),
            "max_m": round(max(errors), 3), "samples": len(errors)}


def _last_finished(brain, behaviour: str):
    """The brain's record of the last `behaviour` it finished, or None."""
    return next((f for f in reversed(brain.finished) if f.name == behaviour), None)


def why_not(brain, behaviour: str) -> str:
    """' (the reason)' when the last `behaviour` ended in anything but DONE, '' otherwise: the
    summary says why a leader did not get there ("no path") instead of a bare unchecked box."""
    last = _last_finished(brain, behaviour)
    if last is None or last.result == ResultCode.DONE:
        return ""
    return f" ({last.result.name}: {last.reason})" if last.reason else f" ({last.result.name})"


def last_result(brain, behaviour: str) -> ResultCode | None:
    """The final result of the last `behaviour` the brain finished, or None."""
    last = _last_finished(brain, behaviour)
    return None if last is None else last.result
