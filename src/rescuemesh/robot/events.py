"""What a robot's brain reports: one frozen dataclass per kind of event (a line of its log), with
typed fields (addresses, message types, results, reasons, sequence numbers, byte counts, hops).

Owns: the event types, their `kind` (BrainEventKind, the text result.json, MCAP and timelines
show) and the one rendering of each as the log's `detail` text. Must not know: how the brain
decides, the simulator, the transport, the clock. Readers compare fields, never `detail`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import ClassVar

from rescuemesh.protocol import DataKind, MessageType, Reason, ResultCode
from rescuemesh.protocol.messages import MESSAGE_CLASS_BY_TYPE
from rescuemesh.robot.naming import MAX_ROBOT_ADDRESS
from rescuemesh.robot.records import LinkLossPolicy


class BrainEventKind(enum.StrEnum):
    """The kind of a brain event; the values are the log's kind texts."""

    POSE_FAULT = "pose_fault"
    POSE_FAULT_CLEARED = "pose_fault_cleared"
    COMMAND_SENT = "command_sent"
    COMMAND_RECEIVED = "command_received"
    COMMAND_REJECTED = "command_rejected"
    COMMAND_DENIED = "command_denied"
    COMMAND_FAILED = "command_failed"
    COMMAND_GIVEN_UP = "command_given_up"
    CONFIRM = "confirm"
    FRAME_REJECTED = "frame_rejected"
    STOPPED = "stopped"
    WAYPOINTS_SKIPPED = "waypoints_skipped"
    DATA_SENT = "data_sent"
    DATA_RECEIVED = "data_received"
    FORWARD_ACCEPTED = "forward_accepted"
    FORWARD_SENT = "forward_sent"
    FORWARD_DATA = "forward_data"
    FORWARD_UNDELIVERED = "forward_undelivered"
    FORWARD_ENDED = "forward_ended"
    FOLLOW_ENDED = "follow_ended"
    FOLLOW_GIVEN_UP = "follow_given_up"
    PEER_RESTARTED = "peer_restarted"
    TRANSFER_FAILED = "transfer_failed"
    BEHAVIOUR_STARTED = "behaviour_started"
    BEHAVIOUR_ENDED = "behaviour_ended"
    LINK_LOST = "link_lost"
    LINK_RESUMED = "link_resumed"
    REPORT_HELD = "report_held"
    REPORT_DELIVERED = "report_delivered"
    REPORT_DROPPED = "report_dropped"


def _who(address: int) -> str:
    return f"robot_{address}" if 1 <= address <= MAX_ROBOT_ADDRESS else str(address)


def message_name(msg_type: MessageType) -> str:
    """A message type as its class is named (Goto, ForwardMsg): the log's words for it."""
    cls = MESSAGE_CLASS_BY_TYPE.get(msg_type)
    return cls.__name__ if cls is not None else msg_type.name


@dataclass(frozen=True, slots=True)
class BrainEvent:
    """Base of every brain event: when (s, rounded to ms) and which robot's log it is in.
    `kind` names the subclass; `detail` renders its fields as the log's text."""

    time_s: float
    robot: str
    kind: ClassVar[BrainEventKind]

    @property
    def detail(self) -> str:
        raise NotImplementedError


@dataclass(frozen=True, slots=True)
class PoseFault(BrainEvent):
    """The robot's own pose cannot travel on the wire: halted."""

    kind: ClassVar = BrainEventKind.POSE_FAULT
    why: str

    @property
    def detail(self) -> str:
        return f"{self.why}: halted, the pose is not sent"


@dataclass(frozen=True, slots=True)
class PoseFaultCleared(BrainEvent):
    kind: ClassVar = BrainEventKind.POSE_FAULT_CLEARED
    x: float
    y: float

    @property
    def detail(self) -> str:
        return f"pose ({self.x:.2f}, {self.y:.2f}) fits the wire again"


@dataclass(frozen=True, slots=True)
class CommandSent(BrainEvent):
    kind: ClassVar = BrainEventKind.COMMAND_SENT
    command: MessageType
    dst: int
    seq: int

    @property
    def detail(self) -> str:
        return f"{message_name(self.command)} to {_who(self.dst)}"


@dataclass(frozen=True, slots=True)
class CommandReceived(BrainEvent):
    """A new command addressed to this robot (before it is admitted or refused)."""

    kind: ClassVar = BrainEventKind.COMMAND_RECEIVED
    command: MessageType
    src: int
    seq: int
    hops: int

    @property
    def detail(self) -> str:
        hops = f" ({self.hops} hops)" if self.hops > 1 else ""
        return f"{message_name(self.command)} from {_who(self.src)} (seq {self.seq}){hops}"


@dataclass(frozen=True, slots=True)
class CommandRejected(BrainEvent):
    """TEMPORARILY_REJECTED: a running command of higher priority holds a resource it needs.
    `holder`/`holder_commander`: the running command's type and sender; None: the robot's own mission."""

    kind: ClassVar = BrainEventKind.COMMAND_REJECTED
    command: MessageType
    src: int
    reason: Reason
    holder: MessageType | None
    holder_commander: int | None

    @property
    def detail(self) -> str:
        holder = "own mission" if self.holder_commander is None else \
            f"{self.holder.name} from {_who(self.holder_commander)}"
        return f"{message_name(self.command)} from {_who(self.src)}: {self.reason.name} by {holder}"


@dataclass(frozen=True, slots=True)
class CommandDenied(BrainEvent):
    """DENIED: a MoveAround whose every waypoint is in an obstacle (BLOCKED), a ForwardMsg the
    forwarder refused (`target`: the address it named)."""

    kind: ClassVar = BrainEventKind.COMMAND_DENIED
    command: MessageType
    reason: Reason
    target: int | None = None

    @property
    def detail(self) -> str:
        if self.command is MessageType.FORWARD_MSG:
            return f"ForwardMsg to {self.target}: {self.reason.name}"
        if self.command is MessageType.MOVE_AROUND and self.reason is Reason.BLOCKED:
            return "MoveAround: every waypoint is inside an obstacle"
        return f"{message_name(self.command)}: {self.reason.name}"


@dataclass(frozen=True, slots=True)
class CommandFailed(BrainEvent):
    """A command answered FAILED at once (a ShowScan/ShowCam with no viewpoint); `why` in words."""

    kind: ClassVar = BrainEventKind.COMMAND_FAILED
    command: MessageType
    reason: Reason
    why: str

    @property
    def detail(self) -> str:
        return f"{message_name(self.command)}: {self.why}"


@dataclass(frozen=True, slots=True)
class CommandGivenUp(BrainEvent):
    """No Confirm for a sent command after `sends` sends."""

    kind: ClassVar = BrainEventKind.COMMAND_GIVEN_UP
    command: MessageType
    dst: int
    seq: int
    sends: int

    @property
    def detail(self) -> str:
        return f"{message_name(self.command)} to {_who(self.dst)} after {self.sends} sends"


@dataclass(frozen=True, slots=True)
class Confirm(BrainEvent):
    """A Confirm (or a later result report) for command `seq` this robot sent to `src`."""

    kind: ClassVar = BrainEventKind.CONFIRM
    command: MessageType
    src: int
    seq: int
    result: ResultCode
    reason: Reason
    progress: int
    hops: int

    @property
    def detail(self) -> str:
        why = f" ({self.reason.name})" if self.reason is not Reason.NONE else ""
        hops = f", {self.hops} hops" if self.hops > 1 else ""
        return f"{message_name(self.command)} by {_who(self.src)}: {self.result.name}{why}{hops}"


@dataclass(frozen=True, slots=True)
class FrameRejected(BrainEvent):
    """A received frame was dropped (`error_type`: the FrameError subclass, `reason`: its words)."""

    kind: ClassVar = BrainEventKind.FRAME_REJECTED
    reason: str
    error_type: str

    @property
    def detail(self) -> str:
        return self.reason


@dataclass(frozen=True, slots=True)
class Stopped(BrainEvent):
    kind: ClassVar = BrainEventKind.STOPPED
    src: int

    @property
    def detail(self) -> str:
        return f"by {_who(self.src)}"


@dataclass(frozen=True, slots=True)
class WaypointsSkipped(BrainEvent):
    """MoveAround waypoints inside obstacles, by index (the closing repeat of the first counted once)."""

    kind: ClassVar = BrainEventKind.WAYPOINTS_SKIPPED
    indices: tuple[int, ...]

    @property
    def detail(self) -> str:
        return ", ".join(str(i) for i in self.indices)


@dataclass(frozen=True, slots=True)
class DataSent(BrainEvent):
    kind: ClassVar = BrainEventKind.DATA_SENT
    data_kind: DataKind
    size: int  # bytes
    dst: int

    @property
    def detail(self) -> str:
        return f"{self.data_kind.name} {self.size} B to {_who(self.dst)}"


@dataclass(frozen=True, slots=True)
class DataReceived(BrainEvent):
    kind: ClassVar = BrainEventKind.DATA_RECEIVED
    data_kind: DataKind
    size: int  # bytes
    src: int

    @property
    def detail(self) -> str:
        return f"{self.data_kind.name} {self.size} B from {_who(self.src)}"


@dataclass(frozen=True, slots=True)
class ForwardAccepted(BrainEvent):
    """A ForwardMsg accepted: `inner` is to go to `target`."""

    kind: ClassVar = BrainEventKind.FORWARD_ACCEPTED
    inner: MessageType
    target: int

    @property
    def detail(self) -> str:
        return f"{message_name(self.inner)} for {_who(self.target)}"


@dataclass(frozen=True, slots=True)
class ForwardSent(BrainEvent):
    kind: ClassVar = BrainEventKind.FORWARD_SENT
    inner: MessageType
    target: int
    sender: int

    @property
    def detail(self) -> str:
        return f"{message_name(self.inner)} to {_who(self.target)} for {_who(self.sender)}"


@dataclass(frozen=True, slots=True)
class ForwardData(BrainEvent):
    """Data answering a forwarded command, passed on from `src` to the robot that asked (`dst`)."""

    kind: ClassVar = BrainEventKind.FORWARD_DATA
    data_kind: DataKind
    size: int  # bytes
    src: int
    dst: int

    @property
    def detail(self) -> str:
        return f"{self.data_kind.name} {self.size} B from {_who(self.src)} to {_who(self.dst)}"


@dataclass(frozen=True, slots=True)
class ForwardUndelivered(BrainEvent):
    kind: ClassVar = BrainEventKind.FORWARD_UNDELIVERED
    dst: int

    @property
    def detail(self) -> str:
        return f"to {_who(self.dst)}: will try again while reachable"


@dataclass(frozen=True, slots=True)
class ForwardEnded(BrainEvent):
    """A ForwardMsg job ended: `answered` is the target's (`peer`'s) result that ended it, or None
    when the target was not reached in `waited_s`."""

    kind: ClassVar = BrainEventKind.FORWARD_ENDED
    result: ResultCode
    reason: Reason
    peer: int
    answered: ResultCode | None = None
    waited_s: float | None = None

    @property
    def detail(self) -> str:
        why = f"{_who(self.peer)} answered {self.answered.name}" if self.answered is not None else \
            f"{_who(self.peer)} not reached in {self.waited_s:g} s"
        return f"{self.result.name} {self.reason.name}: {why}".replace(" NONE", "")


@dataclass(frozen=True, slots=True)
class FollowEnded(BrainEvent):
    """The follower answered a PoseUpdate with something other than ACCEPTED: the stream ends."""

    kind: ClassVar = BrainEventKind.FOLLOW_ENDED
    peer: int
    result: ResultCode

    @property
    def detail(self) -> str:
        return f"{_who(self.peer)} answered {self.result.name}"


@dataclass(frozen=True, slots=True)
class FollowGivenUp(BrainEvent):
    """A pose stream given up: LINK_LOST, or PARTNER_SILENT (no PoseUpdate confirmed for `silent_s`)."""

    kind: ClassVar = BrainEventKind.FOLLOW_GIVEN_UP
    peer: int
    reason: Reason
    silent_s: float | None = None

    @property
    def detail(self) -> str:
        why = "link lost" if self.silent_s is None else f"no PoseUpdate confirmed for {self.silent_s:.1f} s"
        return f"{_who(self.peer)}: {why}"


@dataclass(frozen=True, slots=True)
class PeerRestarted(BrainEvent):
    kind: ClassVar = BrainEventKind.PEER_RESTARTED
    peer: int
    epoch: int

    @property
    def detail(self) -> str:
        return f"{_who(self.peer)} in epoch {self.epoch}"


@dataclass(frozen=True, slots=True)
class TransferFailed(BrainEvent):
    kind: ClassVar = BrainEventKind.TRANSFER_FAILED
    dst: int
    acked: int
    total: int

    @property
    def detail(self) -> str:
        return f"to {_who(self.dst)}: {self.acked} of {self.total} segments acknowledged"


@dataclass(frozen=True, slots=True)
class BehaviourStarted(BrainEvent):
    """`behaviour` (its name: navigate, follow, show-scan ...) started; `beside`: a ShowScan beside a drive."""

    kind: ClassVar = BrainEventKind.BEHAVIOUR_STARTED
    behaviour: str
    beside: bool = False

    @property
    def detail(self) -> str:
        return f"{self.behaviour} (beside the drive)" if self.beside else self.behaviour


@dataclass(frozen=True, slots=True)
class BehaviourEnded(BrainEvent):
    """`behaviour` ended with `result` and `reason`; `why` in words (may be empty)."""

    kind: ClassVar = BrainEventKind.BEHAVIOUR_ENDED
    behaviour: str
    result: ResultCode
    reason: Reason
    why: str = ""

    @property
    def detail(self) -> str:
        return f"{self.behaviour}: {self.result.name} {self.why}".rstrip()


@dataclass(frozen=True, slots=True)
class LinkLost(BrainEvent):
    """A peer sharing a command fell silent (last heard at `last_heard_s`); what the robot does is
    its command's link-loss `policy`: HOLD pauses for `window_s`, CONTINUE goes on with `behaviour`,
    RETURN_TO_BASE drives to its base."""

    kind: ClassVar = BrainEventKind.LINK_LOST
    peer: int
    last_heard_s: float
    policy: LinkLossPolicy
    behaviour: str = ""
    window_s: float = 0.0

    @property
    def detail(self) -> str:
        lost = f"{_who(self.peer)} silent since {self.last_heard_s:.2f} s: "
        if self.policy is LinkLossPolicy.CONTINUE:
            return lost + f"{self.behaviour} continues (link-loss policy continue)"
        if self.policy is LinkLossPolicy.RETURN_TO_BASE:
            return lost + "returning to base (link-loss policy return_to_base)"
        return lost + f"paused, reconnect window {self.window_s:g} s"


@dataclass(frozen=True, slots=True)
class LinkResumed(BrainEvent):
    kind: ClassVar = BrainEventKind.LINK_RESUMED
    peer: int
    hops: int

    @property
    def detail(self) -> str:
        return f"{_who(self.peer)} heard again ({self.hops} hops): resumed"


@dataclass(frozen=True, slots=True)
class ReportHeld(BrainEvent):
    """A final report whose commander is out of reach, kept to deliver later."""

    kind: ClassVar = BrainEventKind.REPORT_HELD
    command: MessageType
    result: ResultCode
    commander: int

    @property
    def detail(self) -> str:
        return f"{self.command.name} {self.result.name} for {_who(self.commander)}, out of reach"


@dataclass(frozen=True, slots=True)
class ReportDelivered(BrainEvent):
    kind: ClassVar = BrainEventKind.REPORT_DELIVERED
    command: MessageType
    result: ResultCode
    commander: int
    held_s: float

    @property
    def detail(self) -> str:
        return f"{self.command.name} {self.result.name} to {_who(self.commander)}, held {self.held_s:.1f} s"


@dataclass(frozen=True, slots=True)
class ReportDropped(BrainEvent):
    kind: ClassVar = BrainEventKind.REPORT_DROPPED
    command: MessageType
    result: ResultCode
    commander: int
    hold_s: float

    @property
    def detail(self) -> str:
        return f"{self.command.name} {self.result.name} for {_who(self.commander)}: not heard in {self.hold_s:g} s"


#: Every kind of brain event, by kind (the control plane registers these, and nothing else).
EVENT_TYPES: dict[BrainEventKind, type[BrainEvent]] = {
    cls.kind: cls for cls in (
        PoseFault, PoseFaultCleared, CommandSent, CommandReceived, CommandRejected, CommandDenied, CommandFailed,
        CommandGivenUp, Confirm, FrameRejected, Stopped, WaypointsSkipped, DataSent, DataReceived, ForwardAccepted,
        ForwardSent, ForwardData, ForwardUndelivered, ForwardEnded, FollowEnded, FollowGivenUp, PeerRestarted,
        TransferFailed, BehaviourStarted, BehaviourEnded, LinkLost, LinkResumed, ReportHeld, ReportDelivered,
        ReportDropped)
}
assert set(EVENT_TYPES) == set(BrainEventKind), "one event type per kind"
