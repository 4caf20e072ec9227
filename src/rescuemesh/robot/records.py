"""What a robot's brain keeps and reports: its settings (BrainConfig), its log lines, the commands
it sent and what became of them, the behaviours it ran and runs, the pose streams it leads, the
kinds of commands by what they oblige, and the pose conversions to and from the wire.

Owns: these records and tables. Must not know: how the brain decides (robot/brain.py), the
simulator, the transport, the clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import MessageType, Pose, Reason, ResultCode
from rescuemesh.robot.behaviours import Behaviour
from rescuemesh.robot.policy import MOTION_LEVEL, Priority, Rank, Resource


@dataclass(frozen=True)
class BrainConfig:
    """Behaviour settings; defaults from the issue and the paper."""

    follow_distance_m: float = 1.0
    pose_update_rate_hz: float = 2.0
    heartbeat_period_s: float = 1.0  # must equal the mesh layer's (it counts missed heartbeats)
    partner_timeout_s: float = 1.5  # a follower halts when its leader sends no PoseUpdate this long (3 updates)
    reconnect_window_s: float = 5.0  # after a peer is lost: resume if heard again within it, else FAILED
    #: Safety nets for a link that works one way only (heartbeats heard, PoseUpdates not): a follower
    #: with no PoseUpdate, a leader with no confirmed PoseUpdate, this long, in s, ends the Follow.
    #: Longer than the link-loss rule (3.5 s + reconnect window), which normally ends it first.
    partner_give_up_s: float = 10.0
    move_around_waypoints: int = 20
    forward_timeout_s: float = 30.0  # how long a ForwardMsg is held for an unreachable target
    forward_capacity: int = 8  # ForwardMsg jobs held at once
    progress_period_s: float = 1.0  # Goto/Return/MoveAround send IN_PROGRESS this often (MAVLink pattern)
    #: A final report (DONE, FAILED, CANCELLED after ACCEPTED) is not confirmed: it goes out this
    #: many times, `final_report_spacing_s` apart, so that losing every copy is unlikely.
    final_report_copies: int = 3
    final_report_spacing_s: float = 0.25
    ranks: dict = field(default_factory=dict)  # robot address -> Rank (a team file or scenario sets it)
    base: Pose2D | None = None  # where Return goes; the runtime sets the start pose
    has_laser: bool = True  # capabilities: ShowScan needs a laser, ShowCam a camera
    has_camera: bool = True
    laser_range_m: float = 5.0  # a viewpoint for ShowScan is at most this far from the position
    camera_range_m: float = 4.0  # ... for ShowCam
    show_timeout_s: float = 120.0  # an open-ended ShowScan/ShowCam (count 0) ends after this
    laser_fov_rad: float = math.radians(240.0)  # a ShowScan runs beside a drive if the spot is in this
    #: The team's robots are switched on within this many s of the run's start (0: all at once): a
    #: robot is off (it does nothing, its radio is off) until `power_on_s(address, spread)`.
    power_on_spread_s: float = 0.0


@dataclass(frozen=True, slots=True)
class BrainEvent:
    """One line of a robot's log, for result.json and timelines."""

    time_s: float
    robot: str
    kind: str
    detail: str = ""


@dataclass
class OutgoingCommand:
    """A command this robot sent, and what became of it: the latest result and reason reported,
    the sends the first Confirm took and the hops it crossed; `failed` when given up unconfirmed."""

    seq: int
    peer: int
    kind: str
    sent_s: float
    msg_type: MessageType = MessageType.STOP
    result: ResultCode | None = None
    reason: Reason = Reason.NONE
    sends: int = 0
    hops: int | None = None
    failed: bool = False


@dataclass
class PoseStream:
    """The leader side of a Follow: PoseUpdates to one follower."""

    follower: int
    follow_seq: int  # the Follow command this stream serves
    next_send_s: float
    last_confirmed_s: float
    failed_in_a_row: int = 0
    paused: bool = False  # the follower's link is lost: no PoseUpdates until it is heard again
    outstanding: set[int] = field(default_factory=set)


@dataclass(frozen=True, slots=True)
class FinishedBehaviour:
    """A behaviour that ran: its name, when it ran (s), its final result, why (code and words)."""

    name: str
    started_s: float
    ended_s: float
    result: ResultCode
    reason: str
    code: Reason = Reason.NONE


@dataclass
class Running:
    behaviour: Behaviour
    started_s: float
    commander: int | None = None  # address of the robot whose command started it; None: own mission
    seq: int | None = None
    msg_type: MessageType | None = None
    priority: Priority = Priority(Rank.PEER, MOTION_LEVEL)
    resources: Resource = Resource.MOTION
    next_report_s: float = 0.0


#: Commands after which the sender streams its pose (PoseUpdates) to the receiver until it ends.
STREAMED = frozenset({MessageType.FOLLOW, MessageType.LAND_ON_TOP})

#: Commands whose receiver reports IN_PROGRESS with a percentage while it runs them.
REPORTS_PROGRESS = frozenset({MessageType.GOTO, MessageType.RETURN, MessageType.MOVE_AROUND,
                              MessageType.SHOW_SCAN, MessageType.SHOW_CAM, MessageType.LAND_ON_TOP})

#: Commands that move the receiver: when one is given up, the sender sends Stop in case it runs.
MOTION_COMMANDS = frozenset({MessageType.FOLLOW, MessageType.MOVE_AROUND, MessageType.GOTO, MessageType.RETURN,
                             MessageType.LAND_ON_TOP})


def power_on_s(address: int, spread_s: float) -> float:
    """When a robot is switched on, in s after the run's start: spread over `spread_s` by address
    (golden-ratio spacing: a team's power-on times are spread, and no two close robots' coincide),
    as an operator switching a team on by hand, or robots booting at their own pace, would give."""
    return (address * 0.7548776662466927) % 1.0 * spread_s


def heartbeat_phase_s(address: int, period_s: float) -> float:
    """When a robot sends its first heartbeat, in s: spread over the period by address (golden-ratio
    spacing), so a team's beacons do not all leave on one control tick as unsynchronised robots'
    would not (collisions on the air otherwise)."""
    return (address * 0.6180339887498949) % 1.0 * period_s


def to_wire_pose(pose: Pose2D) -> Pose:
    return Pose(pose.x, pose.y, 0.0, pose.yaw)


def from_wire_pose(pose: Pose) -> Pose2D:
    return Pose2D(pose.x, pose.y, pose.yaw)
