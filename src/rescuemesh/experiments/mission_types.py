"""A mission's typed form: the team, settings, steps (actions and their triggers), criteria and metrics,
as experiments/mission_spec.py reads them from a file (docs/missions.md documents each).

Owns: the mission's dataclasses and enums. Must not know: YAML, how a mission runs, the simulator.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from pathlib import Path

from rescuemesh.experiments.measures import Measure
from rescuemesh.experiments.mission_measures import TimedMetric
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.robot.policy import Rank


class MissionError(ValueError):
    """A mission file that cannot run; one line naming the file and the line."""


class CommandType(enum.Enum):
    """The nine commands of the paper's Table III, by their mission-file names."""

    FOLLOW = "follow"
    STOP = "stop"
    MOVE_AROUND = "move_around"
    GOTO = "goto"
    RETURN = "return"
    SHOW_CAM = "show_cam"
    SHOW_SCAN = "show_scan"
    LAND_ON_TOP = "land_on_top"
    FORWARD_MSG = "forward_msg"


class RobotModel(enum.Enum):
    TURTLEBOT2 = "turtlebot2"
    QUADROTOR = "quadrotor"


@dataclass(frozen=True)
class CommandSpec:
    """A command and its parameters (which apply depends on `type`; docs/missions.md)."""

    type: CommandType
    pose: tuple[float, float, float] | None = None  # goto
    radius: float | None = None  # move_around
    spot: tuple[float, float] | None = None  # show_scan, show_cam
    count: int = 1  # show_scan, show_cam
    period: float = 1.0  # show_scan, show_cam, in s
    target: str | None = None  # forward_msg
    inner: CommandSpec | None = None  # forward_msg


# --- actions ---

@dataclass(frozen=True)
class SendCommand:
    sender: str
    receiver: str
    command: CommandSpec


@dataclass(frozen=True)
class Drive:
    robot: str
    pose: tuple[float, float, float] | None  # None: `route` or `by`
    route: tuple[tuple[float, float, float], ...] = ()  # each point once the previous one ended DONE
    by: tuple[float, float] | None = None  # an offset in the map frame from where the robot is at the start


@dataclass(frozen=True)
class Outage:
    robot: str
    seconds: float


@dataclass(frozen=True)
class Wait:
    seconds: float


@dataclass(frozen=True)
class EndMission:
    """The mission ends in the control step this step starts."""




@dataclass(frozen=True)
class Settle:
    """Finishes once every one of `robots` has been still (base.settled) since the step started."""

    robots: tuple[str, ...]


Action = SendCommand | Drive | Outage | Wait | EndMission | Settle


# --- triggers ---

@dataclass(frozen=True)
class At:
    time_s: float


@dataclass(frozen=True)
class OnStep:
    step: str
    result: ResultCode | frozenset[ResultCode] | None  # None: when the step has finished; a set: any of them
    started: bool = False  # when the step has started (result None)
    at_receiver: bool = False  # `result` as the receiver ended the command, not as its sender heard

    @property
    def results(self) -> frozenset[ResultCode]:
        return frozenset() if self.result is None else \
            frozenset({self.result}) if isinstance(self.result, ResultCode) else self.result


@dataclass(frozen=True)
class OnRegion:
    robot: str
    region: str


@dataclass(frozen=True)
class OnNear:
    robot: str
    distance: float
    other: str | None
    point: tuple[float, float] | None


@dataclass(frozen=True)
class OnLink:
    robot: str
    peer: str
    lost: bool  # True: `robot` stops hearing `peer`; False: hears it (again)


@dataclass(frozen=True)
class OnSpeed:
    robot: str
    at_least: float  # m/s, the robot's odometry speed


@dataclass(frozen=True)
class OnSettled:
    robot: str  # still (scenarios.base.settled) for SETTLE_S, counted from when the trigger is armed



@dataclass(frozen=True)
class OnKnows:
    robot: str
    peer: str  # `robot` has had `peer`'s Heartbeat (its capabilities and epoch)


@dataclass(frozen=True)
class OnMoving:
    robot: str
    speed: float  # m/s, at least


@dataclass(frozen=True)
class OnLanded:
    robot: str  # a quadrotor that has landed, rotors off


@dataclass(frozen=True)
class OnTeamUp:
    """Every robot is switched on (settings.power_on_spread) and has had a heartbeat period to hear
    the others."""


@dataclass(frozen=True)
class OnAnswered:
    step: str  # the step's command has had its first answer (any result) at its sender


@dataclass(frozen=True)
class OnGivenUp:
    step: str  # the step's command was given up (every copy failed)


Trigger = (At | OnStep | OnRegion | OnNear | OnLink | OnSpeed | OnSettled | OnKnows | OnMoving | OnLanded | OnTeamUp
           | OnGivenUp | OnAnswered)


@dataclass(frozen=True)
class Step:
    name: str
    trigger: Trigger
    after_s: float
    action: Action
    armed_by: str | None = None  # the trigger is checked only once this step has finished
    not_before_s: float = 0.0  # ... and only from this simulated time on
    attempts: int = 3  # a command: how many copies the mission sends if the protocol gives one up
    at_latest: float | None = None  # the step starts at this time at the latest, its trigger held or not
    data_wait_s: float | None = None  # a ShowScan/ShowCam: s to wait after its final result for data (None: 5)
    finish_on_answer: bool = False  # a command step finishes at its first answer, not at its final result


# --- criteria and metrics ---

@dataclass(frozen=True)
class StepResult:
    step: str
    result: ResultCode
    within_s: float | None
    at_receiver: bool = False  # the result the receiver ended the command with


@dataclass(frozen=True)
class StepData:
    step: str
    at_least: int


@dataclass(frozen=True)
class EndsIn:
    robot: str
    region: str


@dataclass(frozen=True)
class EndsNear:
    robot: str
    distance: float
    other: str | None
    point: tuple[float, float] | None


@dataclass(frozen=True)
class NoCollision:
    pass


@dataclass(frozen=True)
class MetricBound:
    metric: str
    minimum: float | None
    maximum: float | None
    relative_to: str | None = None  # the bounds are shares of this metric's value
    equals: tuple = ()  # (VALUE,): the metric must equal VALUE (a name, true/false, a number)


@dataclass(frozen=True)
class StepAnswer:
    step: str
    result: ResultCode
    reason: Reason  # S's command had this result with this reason at its sender


@dataclass(frozen=True)
class StepFinished:
    step: str


@dataclass(frozen=True)
class StepDecoded:
    step: str
    at_least: int  # data items that decode (scans; images that show something)


@dataclass(frozen=True)
class LandsOn:
    robot: str
    carrier: str  # `robot` ends resting on `carrier`'s top plate, rotors off


Criterion = (StepResult | StepData | EndsIn | EndsNear | NoCollision | MetricBound | StepFinished | StepDecoded | LandsOn
             | StepAnswer)


@dataclass(frozen=True)
class Distance:
    name: str
    robots: tuple[str, str]


@dataclass(frozen=True)
class TimeTo:
    name: str
    step: str
    result: ResultCode


@dataclass(frozen=True)
class PathLength:
    name: str
    robot: str



Metric = Distance | TimeTo | PathLength | TimedMetric | Measure


@dataclass(frozen=True)
class RobotSpec:
    name: str
    model: RobotModel = RobotModel.TURTLEBOT2
    start: tuple[float, float, float] | None = None  # None: the map's start for this name
    base: tuple[float, float, float] | None = None  # None: its start
    rank: Rank = Rank.PEER


@dataclass(frozen=True)
class Settings:
    loss: float = 0.0
    relay: bool = True
    radio: str = "ble"
    secure: bool = True
    follow_distance_m: float | None = None  # None: the brain's default (1 m, the paper's)
    power_on_spread_s: float | None = None  # None: the brain's default


@dataclass(frozen=True)
class Mission:
    name: str
    path: Path
    summary: str
    map_path: Path | None  # None: the packaged office
    time_limit_s: float
    settings: Settings
    team: dict[str, RobotSpec]
    steps: tuple[Step, ...]
    criteria: tuple[Criterion, ...]
    metrics: tuple[Metric, ...] = field(default_factory=tuple)
    end_after_s: float = 2.0  # the mission ends this long after its last step finished
    stop_when: tuple[Trigger, ...] = ()  # any of these ends the mission at once

    @staticmethod
    def load(path: str | Path) -> "Mission":
        """Read and validate a mission file (experiments/mission_spec.py load_mission)."""
        from rescuemesh.experiments.mission_spec import load_mission

        return load_mission(Path(path))
