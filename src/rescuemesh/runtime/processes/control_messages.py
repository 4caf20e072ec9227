"""The control plane's messages: the closed set of typed requests a world sends a robot process and
the replies it gets back (docs/processes.md lists each with its fields).

Owns: the message types and which reply answers which request. Must not know: Zenoh, the encoding
(runtime/processes/control_codec.py), keys, what a robot does with a request (runtime/processes/robot_process.py).

There is no generic request: no attribute read, no method call by name. What scenarios and reports
read of a robot travels as a typed status (StatusDelta) with every tick's reply; its counters at the
end as a Report.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from rescuemesh.body import LaserScan, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.mesh.neighbours import NeighbourInfo
from rescuemesh.mesh.node import Transmission
from rescuemesh.mesh.stats import MeshStats
from rescuemesh.protocol import DataKind, Follow, Goto, LandOnTop, MoveAround, Return, ShowCam, ShowScan, Stop
from rescuemesh.protocol.messages import Capability
from rescuemesh.protocol.endpoint import EndpointStats
from rescuemesh.robot.behaviours import Waypoint
from rescuemesh.robot.events import BrainEvent
from rescuemesh.robot.records import FinishedBehaviour, OutgoingCommand
from rescuemesh.runtime.config import SimConfig


class CommandKind(enum.Enum):
    """The brain's command methods a mission script may call (RobotBrain.command_*)."""

    GOTO = "goto"  # peer, goal
    RETURN = "return"  # peer
    FOLLOW = "follow"  # peer
    STOP = "stop"  # peer
    MOVE_AROUND = "move_around"  # peer, radius_m


# --- requests (world -> robot) -----------------------------------------------------------------


@dataclass(frozen=True)
class BodyState:
    """What the world tells a robot about its body at a tick. `scan` is None when unchanged."""

    pose: Pose2D
    odometry: tuple[Pose2D, float, float]
    scan: LaserScan | None


@dataclass(frozen=True)
class RobotSetup:
    """What a robot process is told when it joins: who it is, where, on which grid, with which
    settings. The team key never travels: `config.team_key` is None, and with `key_from_seed`
    False the robot needs `--key FILE` itself."""

    name: str
    start: Pose2D
    config: SimConfig
    grid: OccupancyGrid
    epoch: int
    kind: RobotKind
    top_height: float | None
    key_from_seed: bool
    robot_nonce: bytes  # the robot process's nonce, from its HelloReply: a set-up of another run is refused
    base: Pose2D  # where Return goes: the map's base for this robot, else its start


@dataclass(frozen=True)
class Hello:
    """Before a set-up: the robot answers its process's nonce (HelloReply), which the set-up echoes."""


@dataclass(frozen=True)
class Tick:
    """Step the brain at `now` with this body state; answered by a TickReply."""

    now: float
    body: BodyState


@dataclass(frozen=True)
class Flush:
    """What the stack sends now (after a command from the mission script); answered by a TickReply."""

    now: float


@dataclass(frozen=True)
class Receive:
    """A frame the radio medium delivered; answered by a StackReply."""

    data: bytes
    now: float
    rssi_dbm: float | None
    relay_delay_s: float


@dataclass(frozen=True)
class Timer:
    """The stack's timer is due; answered by a StackReply."""

    now: float


@dataclass(frozen=True)
class NavigateTo:
    """The robot's own mission: drive to `goal` (RobotBrain.navigate_to); answered by a CommandReply."""

    goal: Pose2D
    now: float


@dataclass(frozen=True)
class Command:
    """Send a command to `peer` (RobotBrain.command_*); answered by a CommandReply with its seq."""

    kind: CommandKind
    peer: int
    now: float
    goal: Pose2D | None = None
    radius_m: float | None = None


@dataclass(frozen=True)
class Send:
    """Send a protocol command message as it is (RobotBrain.send); answered by a CommandReply."""

    peer: int
    message: Follow | Goto | Return | Stop | MoveAround | ShowScan | ShowCam | LandOnTop
    now: float


@dataclass(frozen=True)
class Report:
    """The robot's counters for result.json; answered by a ReportReply."""


@dataclass(frozen=True)
class Stats:
    """The process's pid and CPU time; answered by a StatsReply."""


@dataclass(frozen=True)
class Bye:
    """Halt and leave; answered by a Done."""


REQUESTS = (Hello, RobotSetup, Tick, Flush, Receive, Timer, NavigateTo, Command, Send, Report, Stats, Bye)


# --- replies (robot -> world) ------------------------------------------------------------------


@dataclass(frozen=True)
class RunningView:
    """The behaviour a robot runs, as scenarios read it (brain.running.behaviour.name, ...)."""

    name: str
    started_s: float
    waypoints: list[Waypoint] | None = None
    skipped: list[Waypoint] | None = None


@dataclass(frozen=True)
class StatusDelta:
    """What changed in the brain's status since the robot's previous reply: the running behaviour
    (when `running_changed`), behaviours finished, commands sent or updated, log lines and bulk data
    received since, the count of commands given up, and what the peers announced in their Heartbeats
    (the whole table, when it changed)."""

    running_changed: bool = False
    running: RunningView | None = None
    finished: list[FinishedBehaviour] = field(default_factory=list)
    outgoing: list[OutgoingCommand] = field(default_factory=list)
    log: list[BrainEvent] = field(default_factory=list)
    received_data: list[tuple[float, int, DataKind, int, bytes, int]] | None = None
    commands_failed: int = 0
    peer_capabilities: dict[int, Capability] | None = None  # every peer's, when any changed


@dataclass(frozen=True)
class HelloReply:
    robot_nonce: bytes


@dataclass(frozen=True)
class SetupReply:
    timer: float | None


@dataclass(frozen=True)
class StackReply:
    transmissions: list[Transmission]
    timer: float | None


@dataclass(frozen=True)
class TickReply:
    transmissions: list[Transmission]
    timer: float | None
    command: tuple[float, float]
    status: StatusDelta


@dataclass(frozen=True)
class CommandReply:
    seq: int | None
    status: StatusDelta


@dataclass(frozen=True)
class ReportReply:
    endpoint: EndpointStats
    node: MeshStats
    hops_histogram: dict[int, int]
    neighbours: list[NeighbourInfo]


@dataclass(frozen=True)
class StatsReply:
    pid: int
    cpu_s: float


@dataclass(frozen=True)
class Done:
    """The robot halted and leaves."""


@dataclass(frozen=True)
class ErrorReply:
    """The request raised inside the robot: its one-line message and the robot's traceback."""

    message: str
    traceback: str


REPLIES = (HelloReply, SetupReply, StackReply, TickReply, CommandReply, ReportReply, StatsReply, Done, ErrorReply)

#: Which reply answers which request (an ErrorReply may answer any).
ANSWERS = {Hello: HelloReply, RobotSetup: SetupReply, Tick: TickReply, Flush: TickReply, Receive: StackReply, Timer: StackReply,
           NavigateTo: CommandReply, Command: CommandReply, Send: CommandReply, Report: ReportReply,
           Stats: StatsReply, Bye: Done}

MESSAGES = (BodyState, *REQUESTS, RunningView, StatusDelta, *REPLIES)
ENUMS = (CommandKind,)
