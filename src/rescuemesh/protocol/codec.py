"""Frames: the 6-byte header, the payload and the 4-byte CRC-32 around it (docs/protocol.md);
encode_frame/decode_frame and the inner messages of ForwardMsg. Raises only the typed errors of
errors.py. Must not know retries, events, clocks or endpoints.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from enum import IntFlag
from functools import lru_cache

from .errors import (
    EncodeError,
    IntegrityError,
    MalformedPayload,
    TruncatedFrame,
    UnknownMessageType,
    UnsupportedFeature,
    UnsupportedVersion,
)
from .messages import Message, MessageType
from .payloads import PAYLOAD_BYTES, TYPE_BY_VALUE, pull_payload, push_payload
from .wire import (  # noqa: F401  (field pairs and constants re-exported: codec is the public face)
    BROADCAST,
    DEFAULT_TTL,
    FRAME_OVERHEAD_BYTES,
    HEADER_BYTES,
    INTEGRITY_BYTES,
    MAX_ATTEMPT,
    MAX_CONTROL_FRAME_BYTES,
    MAX_FORWARD_INNER_BYTES,
    MAX_FORWARD_MESSAGE_BYTES,
    MAX_EPOCH,
    MAX_MESSAGE_BYTES,
    MAX_SEQ,
    MAX_TTL,
    MAX_UNICAST_ADDRESS,
    POSE_BYTES,
    PROTOCOL_VERSION,
    TYPE_MASK,
    pull_crc,
    pull_period,
    pull_pose,
    pull_radius,
    pull_u8,
    pull_u16,
    push_crc,
    push_period,
    push_pose,
    push_radius,
    push_u8,
    push_u16,
)


class FrameFlags(IntFlag):
    """Header byte 0, bits 5-4 (shifted down by 4). Both belong to the mesh layer (docs/protocol.md
    section 9): the codec never sets them and decode_frame rejects them."""

    NONE = 0
    SEG = 1  # payload is one segment of a bulk message (camera image, scan)
    AUTH = 2  # integrity field is an AES-CCM MIC-32 instead of a CRC-32


_AUTH_BIT = 0x20
_SEG_BIT = 0x10
_NO_FLAGS = FrameFlags.NONE


@dataclass(frozen=True, slots=True)
class Header:
    """The 6 header bytes. `ttl` in hops (0..15), `attempt` 0 = first send (0..3), `src` 0..254,
    `dst` 0..255 (255 = broadcast), `seq` 0..65535."""

    version: int
    flags: FrameFlags
    ttl: int
    attempt: int
    msg_type: MessageType
    src: int
    dst: int
    seq: int


_HEADER = struct.Struct(">BBBBH")
_U32 = struct.Struct(">I")

# Decode fast path, as wire._make_pose: a frozen dataclass __init__ goes through object.__setattr__
# per field; storing straight into the slots builds the same Header about 3x faster.
_new = object.__new__
_SET_HEADER = tuple(
    Header.__dict__[name].__set__
    for name in ("version", "flags", "ttl", "attempt", "msg_type", "src", "dst", "seq")
)


def _make_header(b0: int, b1: int, msg_type: MessageType, src: int, dst: int, seq: int) -> Header:
    """Same as Header(...) (no __post_init__ to skip) from header bytes 0 and 1 and parsed fields."""
    header = _new(Header)
    set_version, set_flags, set_ttl, set_attempt, set_type, set_src, set_dst, set_seq = _SET_HEADER
    set_version(header, b0 >> 6)
    set_flags(header, _NO_FLAGS)
    set_ttl(header, b0 & 0x0F)
    set_attempt(header, b1 >> 6)
    set_type(header, msg_type)
    set_src(header, src)
    set_dst(header, dst)
    set_seq(header, seq)
    return header


def _unicast_only(msg_type: int) -> bool:
    """Everything but a Heartbeat is answered or answers (a SegmentAck answers segments, Data is
    confirmed), so it needs a single destination."""
    return msg_type != MessageType.HEARTBEAT


# --- header: push/pull pair ---------------------------------------------------------------------


def push_header(buf: bytearray, h: Header) -> None:
    """Append the 6 header bytes (layout in docs/protocol.md)."""
    if h.version != PROTOCOL_VERSION:
        raise EncodeError(f"version {h.version} is not {PROTOCOL_VERSION}")
    if h.flags:
        raise EncodeError(f"flags {h.flags!r}: the mesh layer sets AUTH and SEG, never the codec")
    if not (0 <= h.ttl <= MAX_TTL and 0 <= h.attempt <= MAX_ATTEMPT):
        raise EncodeError(f"ttl {h.ttl} or attempt {h.attempt} out of range (0..15, 0..3)")
    if not (0 <= h.src <= MAX_UNICAST_ADDRESS and 0 <= h.dst <= BROADCAST and 0 <= h.seq <= MAX_SEQ):
        raise EncodeError(f"src {h.src}, dst {h.dst} or seq {h.seq} out of range")
    if h.dst == BROADCAST and _unicast_only(h.msg_type):
        raise EncodeError(f"{h.msg_type.name} cannot be broadcast")
    buf += _HEADER.pack(
        (PROTOCOL_VERSION << 6) | h.ttl, (h.attempt << 6) | h.msg_type, h.src, h.dst, h.seq
    )


def pull_header(data: bytes, offset: int = 0) -> tuple[Header, int]:
    """Read the 6 header bytes; the caller has checked the length, version and flags."""
    b0, b1, src, dst, seq = _HEADER.unpack_from(data, offset)
    msg_type = TYPE_BY_VALUE[b1 & TYPE_MASK]
    if msg_type is None:
        raise UnknownMessageType(f"message type {b1 & TYPE_MASK}")
    if src == BROADCAST:
        raise MalformedPayload("source address 255 is the broadcast address")
    if dst == BROADCAST and _unicast_only(msg_type):
        raise MalformedPayload(f"{msg_type.name} sent to broadcast")
    return _make_header(b0, b1, msg_type, src, dst, seq), offset + HEADER_BYTES


#: Types whose frames may be longer than a control frame (logical frames, segmented by the mesh).
BULK_TYPES = frozenset({MessageType.FORWARD_MSG, MessageType.DATA})


def max_frame_bytes(msg_type: MessageType) -> int:
    """Largest frame of this type in bytes (header + largest payload + integrity field). For the
    bulk types (ForwardMsg, Data) this is the largest unsegmented frame, MAX_CONTROL_FRAME_BYTES."""
    if msg_type in BULK_TYPES:
        return MAX_CONTROL_FRAME_BYTES
    return FRAME_OVERHEAD_BYTES + PAYLOAD_BYTES[msg_type][1]


_HEADER_BUGS = (TypeError, ValueError, OverflowError, AttributeError, struct.error)


def encode_frame(header: Header, message: Message) -> bytes:
    """Header + payload + CRC-32. Raises EncodeError for values that cannot be put on the wire."""
    if header.msg_type != getattr(message, "TYPE", None):
        raise EncodeError(f"header type {header.msg_type!r} does not match {message!r}")
    buf = bytearray()
    try:
        push_header(buf, header)
    except EncodeError:
        raise
    except _HEADER_BUGS as exc:
        raise EncodeError(f"cannot encode {header!r}: {exc}") from exc
    push_payload(buf, message)
    if len(buf) + INTEGRITY_BYTES > MAX_MESSAGE_BYTES:
        raise EncodeError(f"frame of {len(buf) + INTEGRITY_BYTES} bytes; at most {MAX_MESSAGE_BYTES}")
    push_crc(buf)
    return bytes(buf)


#: Frames decoded whose results are kept. decode_frame is a pure function of the bytes and its
#: results are frozen, so a result remembered is the result computed: the robots of a simulated team
#: that hear one transmission (20-odd in a convoy of 30) decode its bytes once. An error is not kept.
FRAMES_REMEMBERED = 1024


def decode_frame(data: bytes) -> tuple[Header, Message]:
    """Parse one frame. Checks, in order: length, version, AUTH, CRC, SEG, type, payload.

    Raises only FrameError subclasses (TruncatedFrame, UnsupportedVersion, UnsupportedFeature,
    IntegrityError, UnknownMessageType, MalformedPayload). The last FRAMES_REMEMBERED results are
    remembered (the same frozen Header and Message objects for the same bytes).
    """
    return _remembered(bytes(data))


def parse_frame(data: bytes) -> tuple[Header, Message]:
    """decode_frame without its memory: what a frame not heard before costs (the codec bench)."""
    n = len(data)
    if n < FRAME_OVERHEAD_BYTES:
        raise TruncatedFrame(f"{n} bytes, a frame has at least {FRAME_OVERHEAD_BYTES}")
    if n > MAX_MESSAGE_BYTES:
        raise MalformedPayload(f"{n} bytes, a frame has at most {MAX_MESSAGE_BYTES}")
    b0 = data[0]
    if b0 >> 6 != PROTOCOL_VERSION:
        raise UnsupportedVersion(f"version {b0 >> 6}, this endpoint speaks {PROTOCOL_VERSION}")
    if b0 & _AUTH_BIT:  # the integrity field is a MIC: the mesh layer opens sealed frames
        raise UnsupportedFeature("AUTH flag: a sealed frame, which the mesh layer opens (docs/protocol.md section 12)")
    end = n - INTEGRITY_BYTES
    if zlib.crc32(data[:end]) != _U32.unpack_from(data, end)[0]:
        raise IntegrityError("CRC-32 mismatch")
    if b0 & _SEG_BIT:  # checked after the CRC, which covers it
        raise UnsupportedFeature("SEG flag: a segment frame, which the mesh layer reassembles (docs/mesh.md section 6)")
    header, offset = pull_header(data, 0)
    return header, pull_payload(header.msg_type, data, offset, end)


_remembered = lru_cache(maxsize=FRAMES_REMEMBERED)(parse_frame)


def encode_inner(message: Message) -> bytes:
    """A message without header and CRC (type byte + payload), for ForwardMsg.message."""
    buf = bytearray()
    push_u8(buf, getattr(message, "TYPE", 0))
    push_payload(buf, message)
    return bytes(buf)


def decode_inner(data: bytes) -> Message:
    """Inverse of encode_inner. Raises TruncatedFrame, UnknownMessageType or MalformedPayload."""
    if not data:
        raise TruncatedFrame("empty inner message")
    if data[0] > TYPE_MASK:
        raise UnknownMessageType(f"inner message type byte {data[0]}")
    return pull_payload(data[0], data, 1, len(data))
