"""Payload layouts: one push/pull pair per message, built from the field pairs of wire.py, and the
table of payload sizes. Must not know the header, the CRC, retries or endpoints; the layouts are
documented byte by byte in docs/protocol.md.
"""

from __future__ import annotations

import struct
from typing import Callable

from .errors import EncodeError, MalformedPayload, UnknownMessageType
from .messages import (
    ALL_CAPABILITIES,
    COMMAND_TYPES,
    CAPABILITY_SETS,
    CONFIRMABLE_TYPES,
    PROGRESS_UNKNOWN,
    Confirm,
    Data,
    DataKind,
    Follow,
    ForwardMsg,
    Goto,
    Heartbeat,
    LandOnTop,
    Message,
    MessageType,
    MoveAround,
    PoseUpdate,
    Reason,
    ResultCode,
    Return,
    SegmentAck,
    ShowCam,
    ShowScan,
    Stop,
)
from .wire import (
    BROADCAST,
    DATA_HEADER_BYTES,
    HEADER_BYTES,
    MAX_DATA_BYTES,
    MAX_FORWARD_INNER_BYTES,
    MAX_MESSAGE_BYTES,
    MAX_TTL,
    SEGMENT_ACK_BITMAP_BITS,
    TYPE_MASK,
    pull_period,
    pull_pose,
    pull_radius,
    pull_u16,
    pull_u48,
    push_period,
    push_pose,
    push_radius,
    push_u8,
    push_u16,
    push_u48,
)

#: Type value (0..63) -> MessageType, None where no type is defined.
TYPE_BY_VALUE: tuple[MessageType | None, ...] = tuple(
    MessageType(v) if v in MessageType._value2member_map_ else None for v in range(TYPE_MASK + 1)
)
_RESULT_BY_VALUE: tuple[ResultCode | None, ...] = tuple(
    ResultCode(v) if v in ResultCode._value2member_map_ else None for v in range(256)
)
_REASON_BY_VALUE: tuple[Reason | None, ...] = tuple(
    Reason(v) if v in Reason._value2member_map_ else None for v in range(256)
)
_KIND_BY_VALUE: tuple[DataKind | None, ...] = tuple(
    DataKind(v) if v in DataKind._value2member_map_ else None for v in range(256)
)
#: Segments of the largest logical frame, ceil((8192 - 6) / 16) = 512 (16 bytes per segment, SegN
#: 0..511, docs/mesh.md section 6): a SegmentAck's base is 0..512 (docs/protocol.md section 4).
MAX_SEGMENTS = -(-(MAX_MESSAGE_BYTES - HEADER_BYTES) // 16)
_HEARTBEAT_COMMANDS = frozenset({0, *COMMAND_TYPES})
_CONFIRMABLE = CONFIRMABLE_TYPES


def _push_pose_of(attr: str) -> Callable[[bytearray, Message], None]:
    def push(buf: bytearray, msg: Message) -> None:
        push_pose(buf, getattr(msg, attr))

    return push


def _pull_pose_as(cls: type) -> Callable[[bytes, int, int], Message]:
    def pull(data: bytes, offset: int, end: int) -> Message:
        return cls(pull_pose(data, offset)[0])

    return pull


def _push_empty(buf: bytearray, msg: Message) -> None:
    pass


def _pull_empty_as(cls: type) -> Callable[[bytes, int, int], Message]:
    instance = cls()
    return lambda data, offset, end: instance


def _push_show(buf: bytearray, msg: ShowCam | ShowScan) -> None:
    push_pose(buf, msg.frame)
    push_period(buf, msg.period_s)
    if not 0 <= msg.count <= 255:
        raise EncodeError(f"count {msg.count} out of range 0..255")
    if msg.count != 1 and buf[-1] == 0:  # the period byte just pushed: the rounded period, in units
        raise EncodeError("a repeated ShowCam/ShowScan needs a period of at least 0.1 s")
    push_u8(buf, msg.count)


def _pull_show_as(cls: type) -> Callable[[bytes, int, int], Message]:
    def pull(data: bytes, offset: int, end: int) -> Message:
        frame, offset = pull_pose(data, offset)
        period_s, offset = pull_period(data, offset)
        count = data[offset]
        if count != 1 and period_s == 0.0:
            raise MalformedPayload(f"{cls.__name__} repeated with period 0 s")
        return cls(frame, period_s, count)

    return pull


def _push_forward(buf: bytearray, msg: ForwardMsg) -> None:
    if not 0 <= msg.target <= BROADCAST:
        raise EncodeError(f"target {msg.target} out of range 0..255")
    if not 1 <= len(msg.message) <= MAX_FORWARD_INNER_BYTES:
        raise EncodeError(f"forwarded message of {len(msg.message)} bytes (1..{MAX_FORWARD_INNER_BYTES})")
    push_u8(buf, msg.target)
    buf += msg.message


def _pull_forward(data: bytes, offset: int, end: int) -> ForwardMsg:
    return ForwardMsg(data[offset], bytes(data[offset + 1 : end]))


def _push_move_around(buf: bytearray, msg: MoveAround) -> None:
    push_pose(buf, msg.center)
    push_radius(buf, msg.radius_m)


def _pull_move_around(data: bytes, offset: int, end: int) -> MoveAround:
    center, offset = pull_pose(data, offset)
    return MoveAround(center, pull_radius(data, offset)[0])


def _push_confirm(buf: bytearray, msg: Confirm) -> None:
    if msg.ref_type not in _CONFIRMABLE:
        raise EncodeError(f"ref_type {msg.ref_type!r} is not confirmable")
    if not 0 <= msg.result < len(_RESULT_BY_VALUE) or _RESULT_BY_VALUE[msg.result] is None:
        raise EncodeError(f"result {msg.result!r} is not a ResultCode")
    if not (0 <= msg.progress <= 100 or msg.progress == PROGRESS_UNKNOWN):
        raise EncodeError(f"progress {msg.progress} not in 0..100 or 255")
    push_u16(buf, msg.ref_seq)
    push_u8(buf, msg.ref_type)
    push_u8(buf, msg.result)
    push_u8(buf, msg.progress)
    if not 0 <= msg.reason < len(_REASON_BY_VALUE) or _REASON_BY_VALUE[msg.reason] is None:
        raise EncodeError(f"reason {msg.reason!r} is not a Reason")
    push_u8(buf, msg.reason)


def _pull_confirm(data: bytes, offset: int, end: int) -> Confirm:
    ref_seq, offset = pull_u16(data, offset)
    ref_type = TYPE_BY_VALUE[data[offset]] if data[offset] <= TYPE_MASK else None
    result = _RESULT_BY_VALUE[data[offset + 1]]
    progress = data[offset + 2]
    reason = _REASON_BY_VALUE[data[offset + 3]]
    if ref_type not in _CONFIRMABLE:
        raise MalformedPayload(f"Confirm of non-confirmable type {data[offset]}")
    if result is None:
        raise MalformedPayload(f"result code {data[offset + 1]}")
    if progress > 100 and progress != PROGRESS_UNKNOWN:
        raise MalformedPayload(f"progress {progress}")
    if reason is None:
        raise MalformedPayload(f"reason code {data[offset + 3]}")
    return Confirm(ref_seq, ref_type, result, progress, reason)


def _push_heartbeat(buf: bytearray, msg: Heartbeat) -> None:
    if msg.active_command not in _HEARTBEAT_COMMANDS:
        raise EncodeError(f"active_command {msg.active_command!r} is neither 0 nor a command type")
    if not 0 <= msg.init_ttl <= MAX_TTL:
        raise EncodeError(f"init_ttl {msg.init_ttl} out of range 0..15")
    if not (isinstance(msg.epoch, int) and 0 <= msg.epoch <= 0xFFFFFFFF):
        raise EncodeError(f"epoch {msg.epoch!r} out of range 0..2**32-1")
    if not (isinstance(msg.capabilities, int) and 0 <= msg.capabilities <= ALL_CAPABILITIES):
        raise EncodeError(f"capabilities {msg.capabilities!r} are not Capability bits (0..{ALL_CAPABILITIES})")
    push_u8(buf, msg.active_command)
    push_u8(buf, msg.init_ttl)
    buf += _U32.pack(msg.epoch)
    push_u8(buf, msg.capabilities)


def _pull_heartbeat(data: bytes, offset: int, end: int) -> Heartbeat:
    active, init_ttl = data[offset], data[offset + 1]
    epoch = _U32.unpack_from(data, offset + 2)[0]
    capabilities = data[offset + 6]
    if capabilities > ALL_CAPABILITIES:
        raise MalformedPayload(f"Heartbeat capabilities {capabilities:#x}")
    if active not in _HEARTBEAT_COMMANDS:
        raise MalformedPayload(f"Heartbeat active_command {active}")
    if init_ttl > MAX_TTL:
        raise MalformedPayload(f"Heartbeat init_ttl {init_ttl}")
    return Heartbeat(active, init_ttl, epoch, CAPABILITY_SETS[capabilities])


def _push_segment_ack(buf: bytearray, msg: SegmentAck) -> None:
    if not 0 <= msg.base <= MAX_SEGMENTS:
        raise EncodeError(f"SegmentAck base {msg.base} out of range 0..{MAX_SEGMENTS}")
    if not 0 <= msg.bitmap < 1 << SEGMENT_ACK_BITMAP_BITS:
        raise EncodeError(f"SegmentAck bitmap {msg.bitmap!r} is not a {SEGMENT_ACK_BITMAP_BITS}-bit value")
    push_u16(buf, msg.ref_seq)
    push_u16(buf, msg.base)
    push_u48(buf, msg.bitmap)


def _pull_segment_ack(data: bytes, offset: int, end: int) -> SegmentAck:
    ref_seq, offset = pull_u16(data, offset)
    base, offset = pull_u16(data, offset)
    if base > MAX_SEGMENTS:
        raise MalformedPayload(f"SegmentAck base {base}")
    return SegmentAck(ref_seq, base, pull_u48(data, offset)[0])


def _push_data(buf: bytearray, msg: Data) -> None:
    if not 0 <= msg.kind < len(_KIND_BY_VALUE) or _KIND_BY_VALUE[msg.kind] is None:
        raise EncodeError(f"data kind {msg.kind!r} is not a DataKind")
    if not isinstance(msg.data, (bytes, bytearray)) or len(msg.data) > MAX_DATA_BYTES:
        raise EncodeError(f"Data carries bytes, at most {MAX_DATA_BYTES} of them")
    push_u8(buf, msg.kind)
    push_u16(buf, msg.ref_seq)
    buf += msg.data


def _pull_data(data: bytes, offset: int, end: int) -> Data:
    kind = _KIND_BY_VALUE[data[offset]]
    if kind is None:
        raise MalformedPayload(f"data kind {data[offset]}")
    return Data(kind, pull_u16(data, offset + 1)[0], bytes(data[offset + DATA_HEADER_BYTES : end]))


# class -> (push, min payload bytes, max payload bytes, pull)
_CODECS: dict[type, tuple[Callable, int, int, Callable]] = {
    Follow: (_push_pose_of("frame"), 8, 8, _pull_pose_as(Follow)),
    ShowCam: (_push_show, 10, 10, _pull_show_as(ShowCam)),
    ShowScan: (_push_show, 10, 10, _pull_show_as(ShowScan)),
    LandOnTop: (_push_pose_of("frame"), 8, 8, _pull_pose_as(LandOnTop)),
    Goto: (_push_pose_of("frame"), 8, 8, _pull_pose_as(Goto)),
    Stop: (_push_empty, 0, 0, _pull_empty_as(Stop)),
    ForwardMsg: (_push_forward, 2, 1 + MAX_FORWARD_INNER_BYTES, _pull_forward),
    Return: (_push_empty, 0, 0, _pull_empty_as(Return)),
    MoveAround: (_push_move_around, 10, 10, _pull_move_around),
    Confirm: (_push_confirm, 6, 6, _pull_confirm),
    PoseUpdate: (_push_pose_of("pose"), 8, 8, _pull_pose_as(PoseUpdate)),
    Heartbeat: (_push_heartbeat, 7, 7, _pull_heartbeat),
    SegmentAck: (_push_segment_ack, 10, 10, _pull_segment_ack),
    Data: (_push_data, DATA_HEADER_BYTES, DATA_HEADER_BYTES + MAX_DATA_BYTES, _pull_data),
}
_ENCODERS: dict[type, Callable] = {cls: spec[0] for cls, spec in _CODECS.items()}
_DECODERS: list[tuple[int, int, Callable] | None] = [None] * (TYPE_MASK + 1)
for _cls, (_push, _lo, _hi, _pull) in _CODECS.items():
    _DECODERS[_cls.TYPE] = (_lo, _hi, _pull)

#: MessageType -> (min, max) payload bytes.
PAYLOAD_BYTES: dict[MessageType, tuple[int, int]] = {
    cls.TYPE: (spec[1], spec[2]) for cls, spec in _CODECS.items()
}

_U32 = struct.Struct(">I")
_ENCODE_BUGS = (TypeError, ValueError, OverflowError, AttributeError, struct.error)


def push_payload(buf: bytearray, message: Message) -> None:
    """Append the payload of `message`. EncodeError for anything that is not a valid message."""
    push = _ENCODERS.get(type(message))
    if push is None:
        raise EncodeError(f"not a protocol message: {message!r}")
    try:
        push(buf, message)
    except EncodeError:
        raise
    except _ENCODE_BUGS as exc:  # wrong field types: name the message, not struct internals
        raise EncodeError(f"cannot encode {message!r}: {exc}") from exc


def pull_payload(msg_type: int, data: bytes, offset: int, end: int) -> Message:
    """Parse the payload `data[offset:end]` of a message of type `msg_type` (0..63).

    UnknownMessageType if no such type, MalformedPayload for a wrong length or an out-of-range value.
    """
    spec = _DECODERS[msg_type]
    if spec is None:
        raise UnknownMessageType(f"message type {msg_type}")
    low, high, pull = spec
    if not low <= end - offset <= high:
        raise MalformedPayload(
            f"{TYPE_BY_VALUE[msg_type].name} payload of {end - offset} bytes, expected {low}..{high}"
        )
    return pull(data, offset, end)
