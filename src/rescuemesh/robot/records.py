"""What a robot's brain keeps and reports: its settings (BrainConfig), its log (a ring of
robot/events.py's events), the commands it sent and what became of them, the behaviours it ran and
runs, the pose streams it leads, and the pose conversions to and from the wire.

Owns: these records and tables. Must not know: how the brain decides (robot/brain.py), the
simulator, the transport, the clock.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import EncodeError, MessageType, Pose, Reason, ResultCode
from rescuemesh.protocol.wire import position_to_units
from rescuemesh.robot.behaviours import Behaviour
from rescuemesh.robot.policy import MOTION_LEVEL, Priority, Rank, Resource

if TYPE_CHECKING:
    from rescuemesh.robot.events import BrainEvent


class LinkLossPolicy(enum.Enum):
    """What a robot does with a command when its commander's link is lost (MAVLink's failsafe
    actions: hold, continue the mission, return to launch). The final report of a command whose
    commander is out of reach is held and delivered when it is heard again (robot/custody.py)."""

    HOLD = "hold"  # the paper's rule (IV.A): halt; heard again within the reconnect window: resume; else FAILED
    CONTINUE = "continue"  # carry on; the result is reported when the commander is heard again
    RETURN_TO_BASE = "return_to_base"  # end it FAILED (link lost) at once and drive to the base


def _default_link_loss_policies() -> dict:
    # Following and circling need the commander; a drive to a pose does not (it is where the
    # commander asked the robot to go, and the robot can report there later).
    return {MessageType.GOTO: LinkLossPolicy.CONTINUE, MessageType.RETURN: LinkLossPolicy.CONTINUE}


@dataclass(frozen=True)
class BrainConfig:
    """Behaviour settings; defaults from the issue and the paper."""

    follow_distance_m: float = 1.0
    pose_update_rate_hz: float = 2.0
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
    #: Per command type, what to do when its commander's link is lost; types not listed: HOLD.
    link_loss_policy: dict = field(default_factory=_default_link_loss_policies)
    report_custody_capacity: int = 16  # final reports held for commanders out of reach (robot/custody.py)
    report_custody_hold_s: float = 600.0  # ... each for at most this long, in s
    #: How long a forwarder waits for the final result of a forwarded command that reports progress
    #: (Goto, Return, MoveAround, ShowScan, ShowCam, LandOnTop) once its target accepted it, in s.
    forward_result_timeout_s: float = 600.0

    def policy_for(self, msg_type) -> LinkLossPolicy:
        return self.link_loss_policy.get(msg_type, LinkLossPolicy.HOLD)
    #: The team's robots are switched on within this many s of the run's start (0: all at once): a
    #: robot is off (it does nothing, its radio is off) until `power_on_s(address, spread)`.
    power_on_spread_s: float = 0.0


@dataclass
class OutgoingCommand:
    """A command this robot sent, and what became of it: the latest result and reason reported,
    the sends the first Confirm took and the hops it crossed; `failed` when given up unconfirmed;
    `confirmed_s` when its first Confirm arrived; `automatic` for a Stop the brain sent on its own
    (after a motion command was given up, or a Follow ended by link loss), not asked by a mission."""

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
    confirmed_s: float | None = None
    automatic: bool = False
    reports: dict[ResultCode, int] = field(default_factory=dict)  # Confirms received, by result


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
    paused_for_link: bool = False  # halted by the HOLD link-loss policy, waiting for the commander


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


#: Entries a robot's log keeps (about 2 MB): a peer with the key that sends commands without end
#: cannot grow it further; a long simulated run stays far below it.
LOG_CAPACITY = 50_000


class BrainLog(list):
    """A robot's log: a list of BrainEvents that keeps the latest `capacity` (it lets the oldest go in
    chunks of an eighth, so it holds at most capacity * 9 / 8 and an append costs O(1) on average).
    `total` counts every entry ever appended, `dropped` those let go; `since(n)` gives the entries
    from the n-th appended on that are still held, so a reader that remembers `total` never reads
    one twice. A list, so that it is plain data wherever a brain's state is copied."""

    def __init__(self, capacity: int = LOG_CAPACITY) -> None:
        if not (isinstance(capacity, int) and capacity >= 1):
            raise ValueError(f"capacity must be an int >= 1, got {capacity!r}")
        super().__init__()
        self.capacity = capacity
        self.total = 0

    @property
    def dropped(self) -> int:
        return self.total - len(self)

    def append(self, event: BrainEvent) -> None:
        super().append(event)
        self.total += 1
        if len(self) > self.capacity + self.capacity // 8:
            del self[: len(self) - self.capacity]

    def extend(self, events) -> None:
        """Append each (counted and bounded as `append` does)."""
        for event in events:
            self.append(event)

    def since(self, index: int) -> list[BrainEvent]:
        return self[max(0, index - self.dropped):]


def fits_wire(pose: Pose2D) -> bool:
    """Whether `pose` can travel in a protocol message: x and y finite and within -327.68..327.67 m
    after rounding to cm (docs/protocol.md), yaw finite."""
    try:
        position_to_units(pose.x)
        position_to_units(pose.y)
    except EncodeError:
        return False
    return math.isfinite(pose.yaw)
