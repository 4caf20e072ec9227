"""Header-only view of a frame for the network layer: the checks every frame passes (length,
version, CRC), its kind, the network-cache key and a relay's TTL rewrite. Must not know payload
layouts, retries, events or clocks: relays read the 6-byte header and the integrity field only.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from enum import Enum
from functools import lru_cache

from rescuemesh.protocol import BROADCAST, MessageType
from rescuemesh.protocol.codec import (
    FRAME_OVERHEAD_BYTES, INTEGRITY_BYTES, MAX_CONTROL_FRAME_BYTES, MAX_MESSAGE_BYTES, PROTOCOL_VERSION,
    FrameFlags)
from rescuemesh.protocol.errors import (
    IntegrityError, MalformedPayload, TruncatedFrame, UnsupportedFeature, UnsupportedVersion)
from rescuemesh.protocol.codec import TYPE_MASK

#: Largest frame on the air, in bytes: a Bluetooth Mesh network PDU (Mesh Profile 1.0, 3.4.4), i.e.
#: one BLE advertising AD structure. Segment frames use all of it; other frames stay within 20.
MAX_PDU_BYTES = 29
SEG_BIT = FrameFlags.SEG << 4  # byte 0, bit 4
AUTH_BIT = FrameFlags.AUTH << 4  # byte 0, bit 5
TTL_MASK = 0x0F  # byte 0, bits 3-0
ATTEMPT_SHIFT = 6  # byte 1, bits 7-6: attempt (logical frames) or SAR round (segment frames)

_HEADER = struct.Struct(">BBBBH")
_U32 = struct.Struct(">I")


class FrameKind(Enum):
    """What the network layer does with a frame for us (docs/mesh.md, "Receiving")."""

    PLAIN = "plain"  # delivered upward as it is
    SEGMENT = "segment"  # SEG flag: one piece of a longer logical frame, for reassembly
    SEGMENT_ACK = "segment_ack"  # consumed by the SAR sender, never delivered


@dataclass(frozen=True, slots=True)
class FrameView:
    """The header of a checked frame: `ttl` in hops, `msg_type` the raw 6-bit type (relays do not
    need to know it), `src` 0..254, `dst` 0..255, `seq` 0..65535."""

    kind: FrameKind
    ttl: int
    msg_type: int
    src: int
    dst: int
    seq: int


def seal(body: bytes | bytearray) -> bytes:
    """`body` followed by its CRC-32 (zlib.crc32, big-endian), as protocol/wire.push_crc does."""
    return bytes(body) + _U32.pack(zlib.crc32(body))


def crc_ok(data: bytes) -> bool:
    """True if the last 4 bytes are the CRC-32 of the bytes before them (len(data) >= 4)."""
    end = len(data) - INTEGRITY_BYTES
    return zlib.crc32(data[:end]) == _U32.unpack_from(data, end)[0]


def _check_common(data: bytes) -> int:
    """Length, version, AUTH and CRC checks shared by received and sent frames; returns byte 0."""
    if len(data) < FRAME_OVERHEAD_BYTES:
        raise TruncatedFrame(f"{len(data)} bytes, a frame has at least {FRAME_OVERHEAD_BYTES}")
    b0 = data[0]
    if b0 >> 6 != PROTOCOL_VERSION:
        raise UnsupportedVersion(f"version {b0 >> 6}, this node speaks {PROTOCOL_VERSION}")
    if b0 & AUTH_BIT:
        raise UnsupportedFeature("AUTH flag: a sealed frame, to be opened first (a node without a sealer drops it)")
    if not crc_ok(data):
        raise IntegrityError("CRC-32 mismatch")
    return b0


#: Frames read on the air whose headers are kept (read_on_air is a pure function of the bytes, and
#: a simulated team's 20-odd nodes that hear a frame read the same bytes: they parse it once).
HEADERS_REMEMBERED = 1024


def read_on_air(data: bytes) -> FrameView:
    """Check a frame heard on the air and read its header. Raises only protocol FrameErrors:
    TruncatedFrame, UnsupportedVersion, UnsupportedFeature (AUTH), IntegrityError (CRC) and
    MalformedPayload (longer than 20 bytes without SEG, longer than 29 with it, source 255).
    The last HEADERS_REMEMBERED headers read are remembered (an error is not)."""
    return _read_on_air(bytes(data))


@lru_cache(maxsize=HEADERS_REMEMBERED)
def _read_on_air(data: bytes) -> FrameView:
    b0 = _check_common(data)
    limit = MAX_PDU_BYTES if b0 & SEG_BIT else MAX_CONTROL_FRAME_BYTES
    if len(data) > limit:
        raise MalformedPayload(f"{len(data)}-byte frame on the air, at most {limit} bytes")
    b1, src, dst, seq = _HEADER.unpack_from(data, 0)[1:]
    if src == BROADCAST:
        raise MalformedPayload("source address 255 is the broadcast address")
    msg_type = b1 & TYPE_MASK
    if b0 & SEG_BIT:
        kind = FrameKind.SEGMENT
    elif msg_type == MessageType.SEGMENT_ACK:
        kind = FrameKind.SEGMENT_ACK
    else:
        kind = FrameKind.PLAIN
    return FrameView(kind, b0 & TTL_MASK, msg_type, src, dst, seq)


def read_logical(frame: bytes) -> FrameView:
    """Check a logical frame handed down by the endpoint (10..MAX_MESSAGE_BYTES bytes, no SEG).
    Raises the same FrameErrors as read_on_air (the node turns them into ValueError)."""
    b0 = _check_common(frame)
    if len(frame) > MAX_MESSAGE_BYTES:
        raise MalformedPayload(f"{len(frame)}-byte frame, at most {MAX_MESSAGE_BYTES} bytes")
    if b0 & SEG_BIT:
        raise MalformedPayload("SEG flag set: the mesh node segments frames itself")
    b1, src, dst, seq = _HEADER.unpack_from(frame, 0)[1:]
    if src == BROADCAST:
        raise MalformedPayload("source address 255 is the broadcast address")
    return FrameView(FrameKind.PLAIN, b0 & TTL_MASK, b1 & TYPE_MASK, src, dst, seq)


def cache_key(data: bytes, epoch: int | None = None) -> bytes:
    """Network message cache key: the frame without its TTL nibble and its integrity field, after
    the 4 bytes of `epoch` for a sealed frame (a rebooted source's frame may repeat an old one but
    for its epoch).

    A frame heard through two relays (TTL differs) has one key; a resend (attempt bits) or a
    retransmitted segment (round bits) has a new one (docs/mesh.md, "The cache").
    """
    key = bytes((data[0] & ~TTL_MASK & 0xFF,)) + data[1:-INTEGRITY_BYTES]
    return key if epoch is None else epoch.to_bytes(4, "big") + key


def with_ttl(data: bytes, ttl: int) -> bytes:
    """The same frame with TTL `ttl` (0..15) and its CRC-32 recomputed: what a relay sends."""
    body = bytearray(data[:-INTEGRITY_BYTES])
    body[0] = (body[0] & ~TTL_MASK & 0xFF) | ttl
    return seal(body)

