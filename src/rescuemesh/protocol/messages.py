"""The protocol's vocabulary: message types, result codes, one frozen dataclass per message (paper
Table III, plus Confirm, PoseUpdate and Heartbeat). Must not know bytes, headers, retries or robots:
the wire format lives in wire.py, payloads.py and codec.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import ClassVar, Union


class MessageType(IntEnum):
    """Message type, bits 5-0 of header byte 1 (0..63); see docs/protocol.md.

    0 is reserved (a Heartbeat's `active_command` uses it for "idle"). Commands take 1..31 in the
    order of paper Table III; protocol messages take 32..63.
    """

    FOLLOW = 1
    SHOW_CAM = 2
    SHOW_SCAN = 3
    LAND_ON_TOP = 4
    GOTO = 5
    STOP = 6
    FORWARD_MSG = 7
    RETURN = 8
    MOVE_AROUND = 9
    CONFIRM = 32
    POSE_UPDATE = 33
    HEARTBEAT = 34
    SEGMENT_ACK = 35
    DATA = 36


class ResultCode(IntEnum):
    """Outcome of a command or PoseUpdate carried by a Confirm (modelled on MAVLink MAV_RESULT).

    ACCEPTED and IN_PROGRESS are interim; the others are final (see `reliability.RESULT_TRANSITIONS`).
    """

    ACCEPTED = 0  # valid and started (PoseUpdate: "I am following you")
    IN_PROGRESS = 1  # still running; Confirm.progress says how far (0-100 %, 255 unknown)
    DONE = 2  # finished successfully
    DENIED = 3  # understood but refused now (busy, unsafe; PoseUpdate: "I am not following you")
    UNSUPPORTED = 4  # this robot cannot do it (no camera for ShowCam, cannot fly for LandOnTop)
    FAILED = 5  # started but could not finish (goal unreachable, partner lost)
    CANCELLED = 6  # stopped by a Stop or replaced by a newer motion command
    TEMPORARILY_REJECTED = 7  # a command of higher priority holds what it needs; ask again later


class Reason(IntEnum):
    """Why a command ended as it did, carried by a Confirm beside its result (MAVLink COMMAND_ACK's
    result_param2 plays this role). NONE for ACCEPTED, IN_PROGRESS and DONE."""

    NONE = 0
    STOPPED = 1  # a Stop ended it
    REPLACED = 2  # a newer motion command replaced it
    LINK_LOST = 3  # the partner was lost and not heard again within the reconnect window
    TIMEOUT = 4  # not done in time (a ForwardMsg whose target stayed unreachable)
    NOT_DELIVERED = 5  # a forwarded message was sent but never confirmed by its target
    NO_PATH = 6  # navigation found no path
    STUCK = 7  # navigation made no progress
    PARTNER_SILENT = 8  # the leader sent no PoseUpdate for too long
    NOT_FOLLOWING = 9  # a PoseUpdate from a robot we do not follow
    BLOCKED = 10  # every waypoint is inside an obstacle
    BAD_REQUEST = 11  # the request cannot be carried out as given (a malformed inner message)
    UNKNOWN_TARGET = 12  # a ForwardMsg to our own or the broadcast address
    BUSY = 13  # no room to take it on now (all forwarding slots held); ask again later
    MOTION_HELD = 14  # TEMPORARILY_REJECTED: a command of higher priority drives the robot
    CAMERA_HELD = 15  # TEMPORARILY_REJECTED: a command of higher priority uses the camera
    LASER_HELD = 16  # TEMPORARILY_REJECTED: a command of higher priority uses the laser
    NO_RENDERER = 17  # ShowCam: this robot cannot render camera images (no GL)
    NO_VIEWPOINT = 18  # ShowScan/ShowCam: no reachable spot sees the requested position
    NO_SENSOR = 19  # UNSUPPORTED: this robot has no camera / no laser for ShowCam / ShowScan
    NOT_FLYING = 20  # UNSUPPORTED: LandOnTop needs a flying robot; or the sender has no top to land on


class Capability(IntFlag):
    """What a robot can do, announced in its Heartbeats (paper Table III's "Target" column)."""

    NONE = 0
    FLYING = 1  # a flying robot (LandOnTop); otherwise a ground robot
    CAMERA = 2  # ShowCam
    LASER = 4  # ShowScan
    LANDING_PAD = 8  # a top a flying robot may land on
    RELAY = 16  # relays frames for others (the mesh layer's relay feature)


#: Every Capability bit (a Heartbeat with others set is malformed).
ALL_CAPABILITIES = 0x1F
#: Every valid set of Capability bits, by value: reading a Heartbeat looks its bits up here
#: (Capability(bits) builds a Flag member anew each call, a few us: every robot of a team of 30 reads
#: 29 Heartbeats a period).
CAPABILITY_SETS: tuple[Capability, ...] = tuple(Capability(bits) for bits in range(ALL_CAPABILITIES + 1))


class DataKind(IntEnum):
    """What a Data message carries."""

    RAW = 0
    LASER_SCAN = 1
    IMAGE_JPEG = 2
    IMAGE_PNG = 3


#: Confirm.progress value meaning "progress unknown" (MAVLink COMMAND_ACK.progress uses the same).
PROGRESS_UNKNOWN = 255


@dataclass(frozen=True, slots=True)
class Pose:
    """A pose in the `map` frame (REP-103): position `x`, `y`, `z` in m, heading `yaw` in rad about z.

    The protocol's own type (it must not import rescuemesh.geometry). On the wire: cm and 2*pi/65536 rad.
    """

    x: float
    y: float
    z: float
    yaw: float


# --- commands (paper Table III) -------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Follow:
    """Follow the sender, whose pose is `frame`; PoseUpdates follow (paper IV.A)."""

    TYPE: ClassVar[MessageType] = MessageType.FOLLOW
    frame: Pose


@dataclass(frozen=True, slots=True)
class ShowCam:
    """Send camera images of `frame` (paper Table III: "Frame, repeat, timeout, repeat count").

    `count` = 1: send once; `count` = 0: repeat until Stop; otherwise `count` images.
    `period_s`: seconds between repeats (0.1 s resolution, 0..25.5 s; > 0 unless `count` is 1).
    """

    TYPE: ClassVar[MessageType] = MessageType.SHOW_CAM
    frame: Pose
    period_s: float
    count: int


@dataclass(frozen=True, slots=True)
class ShowScan:
    """Send laser scans taken at `frame`; `period_s` and `count` as for ShowCam (paper Table III)."""

    TYPE: ClassVar[MessageType] = MessageType.SHOW_SCAN
    frame: Pose
    period_s: float
    count: int


@dataclass(frozen=True, slots=True)
class LandOnTop:
    """A flying robot lands on the ground robot whose pose is `frame` (paper Table III)."""

    TYPE: ClassVar[MessageType] = MessageType.LAND_ON_TOP
    frame: Pose


@dataclass(frozen=True, slots=True)
class Goto:
    """Move to `frame` (paper Table III)."""

    TYPE: ClassVar[MessageType] = MessageType.GOTO
    frame: Pose


@dataclass(frozen=True, slots=True)
class Stop:
    """Stop the running command and the navigation goal (paper IV.B)."""

    TYPE: ClassVar[MessageType] = MessageType.STOP


@dataclass(frozen=True, slots=True)
class ForwardMsg:
    """Forward `message` to robot `target` (paper Table III).

    `message` is an inner message (type byte + payload, see `codec.encode_inner`). Up to 9 bytes
    the frame is a 20-byte control frame; a longer one (up to MAX_FORWARD_INNER_BYTES) makes a
    logical frame that the mesh layer segments.
    """

    TYPE: ClassVar[MessageType] = MessageType.FORWARD_MSG
    target: int
    message: bytes


@dataclass(frozen=True, slots=True)
class Return:
    """Return to "Base" (paper Table III)."""

    TYPE: ClassVar[MessageType] = MessageType.RETURN


@dataclass(frozen=True, slots=True)
class MoveAround:
    """Circle `center` anticlockwise at `radius_m` m (> 0, 0.01 m resolution; paper IV.C)."""

    TYPE: ClassVar[MessageType] = MessageType.MOVE_AROUND
    center: Pose
    radius_m: float


# --- protocol messages ----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Confirm:
    """Answer to the command or PoseUpdate sent with sequence number `ref_seq` and type `ref_type`.

    `progress`: 0-100 %, or PROGRESS_UNKNOWN (255); `reason` says why a command ended. Paper IV.A: COMMAND_CONFIRM; result codes after
    MAVLink COMMAND_ACK.
    """

    TYPE: ClassVar[MessageType] = MessageType.CONFIRM
    ref_seq: int
    ref_type: MessageType
    result: ResultCode
    progress: int = PROGRESS_UNKNOWN
    reason: Reason = Reason.NONE


@dataclass(frozen=True, slots=True)
class PoseUpdate:
    """The leader's latest pose, streamed during Follow (paper IV.A: geometry_msgs/PoseStamped)."""

    TYPE: ClassVar[MessageType] = MessageType.POSE_UPDATE
    pose: Pose


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """Broadcast liveness beacon (after Bluetooth Mesh heartbeats).

    `active_command`: MessageType value of the running command, 0 when idle. `init_ttl`: the TTL the
    frame was sent with (0..15), so a receiver counts hops as init_ttl - ttl + 1. `epoch`: the
    sender's boot/wrap counter (0..2**32-1) that authenticated frames use in their nonce; in a
    sealed Heartbeat it travels in the clear, authenticated (docs/protocol.md section 12).
    """

    TYPE: ClassVar[MessageType] = MessageType.HEARTBEAT
    active_command: int
    init_ttl: int
    epoch: int = 0
    capabilities: int = 0  # Capability bits


@dataclass(frozen=True, slots=True)
class SegmentAck:
    """Block acknowledgement of a segmented message (Bluetooth Mesh lower transport Segment
    Acknowledgment, widened): every segment with index < `base` arrived, and bit i of `bitmap`
    (48 bits) says whether segment `base + i` arrived. Sent by the mesh layer, never confirmed."""

    TYPE: ClassVar[MessageType] = MessageType.SEGMENT_ACK
    ref_seq: int
    base: int
    bitmap: int


@dataclass(frozen=True, slots=True)
class Data:
    """Bulk data (a laser scan, a camera image ...) answering the command `ref_seq`; longer than a
    control frame, so the mesh layer segments it. Confirmed like a command."""

    TYPE: ClassVar[MessageType] = MessageType.DATA
    kind: DataKind
    ref_seq: int
    data: bytes


Command = Union[Follow, ShowCam, ShowScan, LandOnTop, Goto, Stop, ForwardMsg, Return, MoveAround]
Message = Union[Command, Confirm, PoseUpdate, Heartbeat, SegmentAck, Data]

COMMAND_CLASSES: tuple[type, ...] = (
    Follow, ShowCam, ShowScan, LandOnTop, Goto, Stop, ForwardMsg, Return, MoveAround,
)
MESSAGE_CLASSES: tuple[type, ...] = COMMAND_CLASSES + (Confirm, PoseUpdate, Heartbeat, SegmentAck, Data)

#: Types of the commands of paper Table III.
COMMAND_TYPES: frozenset[MessageType] = frozenset(cls.TYPE for cls in COMMAND_CLASSES)
#: Types a receiver must answer with a Confirm (and a sender retries): commands, PoseUpdate, Data.
CONFIRMABLE_TYPES: frozenset[MessageType] = COMMAND_TYPES | {MessageType.POSE_UPDATE, MessageType.DATA}
#: MessageType -> dataclass.
MESSAGE_CLASS_BY_TYPE: dict[MessageType, type] = {cls.TYPE: cls for cls in MESSAGE_CLASSES}

_COMMAND_CLASS_SET = frozenset(COMMAND_CLASSES)


def is_command(msg: object) -> bool:
    """True if `msg` is one of the commands of paper Table III."""
    return type(msg) in _COMMAND_CLASS_SET
