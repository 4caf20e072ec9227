"""Events the Endpoint hands to its application (`Endpoint.next_event()`), each an EndpointEvent with `now`.
Owns the event dataclasses only; must not know how they are produced or what the application does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from .messages import Command, DataKind, Message, MessageType, Pose, Reason, ResultCode


@dataclass(frozen=True, slots=True)
class EndpointEvent:
    """Base class of every endpoint event (as every mesh event is a MeshEvent): consumers dispatch on
    `type(event)` through a table. Every event carries `now` (s); one for a received frame also carries
    `hops`, the radio hops it crossed (a mesh-layer fact)."""


@dataclass(frozen=True, slots=True)
class CommandReceived(EndpointEvent):
    """A new (not a resend) command addressed to us. Answer it with `Endpoint.confirm(src, seq, ...)`."""

    src: int
    seq: int
    command: Command
    now: float
    hops: int = 1


@dataclass(frozen=True, slots=True)
class PoseUpdateReceived(EndpointEvent):
    """A new PoseUpdate addressed to us. Confirm it: ACCEPTED if following `src`, DENIED otherwise."""

    src: int
    seq: int
    pose: Pose
    now: float
    hops: int = 1


@dataclass(frozen=True, slots=True)
class ConfirmReceived(EndpointEvent):
    """A Confirm from `src` for our frame `ref_seq`.

    solicited: it answers a frame we were still retrying; `sends` is how many sends that took and
    `rtt_s` the time in s since the last send. Otherwise (a later result report or a duplicate
    Confirm) solicited is False, sends 0 and rtt_s None.
    """

    src: int
    ref_seq: int
    ref_type: MessageType
    result: ResultCode
    progress: int
    solicited: bool
    sends: int
    rtt_s: float | None
    now: float
    reason: Reason = Reason.NONE
    hops: int = 1


@dataclass(frozen=True, slots=True)
class DataReceived(EndpointEvent):
    """New bulk data from `src` (frame `seq`), answering our command `ref_seq`. Confirm it."""

    src: int
    seq: int
    kind: DataKind
    ref_seq: int
    data: bytes
    now: float
    hops: int = 1


@dataclass(frozen=True, slots=True)
class DeliveryFailed(EndpointEvent):
    """No Confirm for frame `seq` to `dst` after `sends` (= max_sends) sends; retrying stopped."""

    dst: int
    seq: int
    message: Message
    sends: int
    now: float


@dataclass(frozen=True, slots=True)
class HeartbeatReceived(EndpointEvent):
    """A Heartbeat from `src`; `active_command` is a MessageType value or 0 when idle."""

    src: int
    active_command: int
    now: float
    hops: int = 1
    capabilities: int = 0  # Capability bits the sender announces


@dataclass(frozen=True, slots=True)
class FrameRejected(EndpointEvent):
    """A received frame was dropped: `error_type` is the FrameError subclass name, `reason` its text."""

    reason: str
    error_type: str
    now: float


#: Every endpoint event type (`EndpointEvent`'s subclasses), as a type for annotations.
Event = Union[
    CommandReceived,
    PoseUpdateReceived,
    ConfirmReceived,
    DataReceived,
    DeliveryFailed,
    HeartbeatReceived,
    FrameRejected,
]


# Every robot hears every neighbour's Heartbeat (N^2 a period): the event is built straight into its
# slots, as codec._make_header builds a Header. The same object as HeartbeatReceived(...).
_new = object.__new__
_SET_HEARTBEAT = tuple(HeartbeatReceived.__dict__[name].__set__
                       for name in ("src", "active_command", "now", "hops", "capabilities"))


def heartbeat_received(src: int, active_command: int, now: float, hops: int, capabilities: int) -> HeartbeatReceived:
    """HeartbeatReceived(src, active_command, now, hops, capabilities), built faster."""
    event = _new(HeartbeatReceived)
    set_src, set_active, set_now, set_hops, set_capabilities = _SET_HEARTBEAT
    set_src(event, src)
    set_active(event, active_command)
    set_now(event, now)
    set_hops(event, hops)
    set_capabilities(event, capabilities)
    return event
