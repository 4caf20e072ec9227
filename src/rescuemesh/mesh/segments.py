"""Segment frames, byte by byte (docs/mesh.md, "Segment frames"): splitting a logical frame, reading
a segment, the block ack (base, bitmap) and rebuilding the logical frame. Must not know timers,
retransmission rounds' timing, events or relays; after Bluetooth Mesh Profile 1.0, 3.5.2.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

from rescuemesh.protocol.codec import (
    FRAME_OVERHEAD_BYTES, HEADER_BYTES, INTEGRITY_BYTES, MAX_ATTEMPT, MAX_MESSAGE_BYTES, MAX_TTL)
from rescuemesh.protocol.errors import MalformedPayload
from rescuemesh.protocol.codec import TYPE_MASK

from .frames import ATTEMPT_SHIFT, MAX_PDU_BYTES, SEG_BIT, TTL_MASK, seal

SEGMENT_HEADER_BYTES = 3  # SegO (12 bits) | SegN (12 bits), big-endian
SEGMENT_DATA_BYTES = 16  # 29-byte PDU - 6 header - 3 segment header - 4 CRC
MIN_SEGMENT_FRAME_BYTES = HEADER_BYTES + SEGMENT_HEADER_BYTES + 1 + INTEGRITY_BYTES  # 14
#: Segments of the largest logical frame: ceil((8192 - 6) / 16) = 512, so SegN <= 511.
MAX_SEGMENTS = -(-(MAX_MESSAGE_BYTES - HEADER_BYTES) // SEGMENT_DATA_BYTES)
MAX_ROUND_BITS = 3  # the round travels in 2 bits (byte 1, bits 7-6) and wraps
BLOCK_ACK_BITS = 48  # SegmentAck.bitmap: segments base .. base + 47
_SEG_FIELD = 0xFFF
_DATA_START = HEADER_BYTES + SEGMENT_HEADER_BYTES  # 9
_CLEAR_SEG_TTL = ~(SEG_BIT | TTL_MASK) & 0xFF

assert HEADER_BYTES + SEGMENT_HEADER_BYTES + SEGMENT_DATA_BYTES + INTEGRITY_BYTES == MAX_PDU_BYTES


@dataclass(frozen=True, slots=True)
class Segment:
    """A checked segment frame: `seg_o` its index, `seg_n` the last index (both 0..511), `round`
    the retransmission round mod 4, `data` its 1..16 bytes of the logical frame (after its header)."""

    seg_o: int
    seg_n: int
    round: int
    msg_type: int
    data: bytes


def segment_count(frame_bytes: int) -> int:
    """Segments needed for a logical frame of `frame_bytes` bytes (its 6 header bytes are not sent)."""
    return -(-(frame_bytes - HEADER_BYTES) // SEGMENT_DATA_BYTES)


def make_segment(frame: bytes, index: int, round_: int) -> bytes:
    """Segment `index` of logical `frame`, sent in retransmission round `round_` (>= 0, sent mod 4).

    Bytes 0-5: the frame's header with SEG set and the attempt bits replaced by the round; 6-8: SegO
    and SegN; then the frame's bytes 6 + 16 * index onward (at most 16); then a CRC-32 over all that.
    """
    last = segment_count(len(frame)) - 1
    start = HEADER_BYTES + SEGMENT_DATA_BYTES * index
    body = bytearray(frame[:HEADER_BYTES])
    body[0] |= SEG_BIT
    body[1] = ((round_ & MAX_ROUND_BITS) << ATTEMPT_SHIFT) | (frame[1] & TYPE_MASK)
    body += ((index << 12) | last).to_bytes(SEGMENT_HEADER_BYTES, "big")
    body += frame[start : start + SEGMENT_DATA_BYTES]
    return seal(body)


def read_segment_header(data: bytes) -> tuple[int, int]:
    """(SegO, SegN) of a segment frame of at least 9 bytes, unchecked (for relay metadata)."""
    value = int.from_bytes(data[HEADER_BYTES:_DATA_START], "big")
    return value >> 12, value & _SEG_FIELD


def parse_segment(data: bytes) -> Segment:
    """Read a segment frame whose header and CRC were checked (frames.read_on_air). Raises
    MalformedPayload for: too short, SegO > SegN, more than 512 segments, a segment other than the
    last not carrying exactly 16 bytes, or a last segment that makes the logical frame shorter than
    10 or longer than MAX_MESSAGE_BYTES bytes."""
    if not MIN_SEGMENT_FRAME_BYTES <= len(data) <= MAX_PDU_BYTES:
        raise MalformedPayload(f"{len(data)}-byte segment frame, expected 14..29")
    seg_o, seg_n = read_segment_header(data)
    if seg_o > seg_n:
        raise MalformedPayload(f"SegO {seg_o} > SegN {seg_n}")
    if seg_n >= MAX_SEGMENTS:
        raise MalformedPayload(f"{seg_n + 1} segments: more than {MAX_MESSAGE_BYTES} bytes")
    chunk = bytes(data[_DATA_START:-INTEGRITY_BYTES])
    if seg_o < seg_n and len(chunk) != SEGMENT_DATA_BYTES:
        raise MalformedPayload(f"segment {seg_o} of {seg_n + 1} carries {len(chunk)} bytes, not 16")
    if seg_o == seg_n:
        total = HEADER_BYTES + SEGMENT_DATA_BYTES * seg_n + len(chunk)
        if not FRAME_OVERHEAD_BYTES <= total <= MAX_MESSAGE_BYTES:
            raise MalformedPayload(f"last segment makes a {total}-byte frame")
    return Segment(seg_o, seg_n, data[1] >> ATTEMPT_SHIFT, data[1] & TYPE_MASK, chunk)


def block_ack(pieces: list[bytes | None], base: int) -> tuple[int, int]:
    """(base, bitmap) for the pieces held: every index < base held, bit i set = base + i held.

    `base` is a lower bound already known (the previous ack's base); it only moves forward.
    """
    total = len(pieces)
    while base < total and pieces[base] is not None:
        base += 1
    bitmap = 0
    for i in range(min(BLOCK_ACK_BITS, total - base)):
        if pieces[base + i] is not None:
            bitmap |= 1 << i
    return base, bitmap


def acked_indices(base: int, bitmap: int, total: int) -> list[int]:
    """Segment indices a SegmentAck (base, bitmap) reports for a message of `total` segments."""
    indices = list(range(min(base, total)))
    bit = 0
    while bitmap >> bit and base + bit < total:
        if (bitmap >> bit) & 1:
            indices.append(base + bit)
        bit += 1
    return indices


def rebuild_frame(first: bytes, body: bytes, ttl_guess: int, min_ttl: int) -> bytes | None:
    """The logical frame the source's endpoint encoded, or None if `body` is not one.

    `first`: bytes 0-5 of any segment of it; `body`: the reassembled data (payload + CRC). The
    segments carry neither the frame's original TTL (relays lower it) nor its attempt bits (the
    round replaces them), so the frame's own CRC-32 tells: TTL `ttl_guess` (the source's
    init_ttl) is tried first, then every TTL from `min_ttl` (the highest TTL a segment arrived
    with) to 15, each with attempt 0..3. The common case costs one CRC over the frame; the worst
    (no match: a corrupt or mixed-up reassembly) 64.
    """
    if len(body) < INTEGRITY_BYTES:
        return None
    payload, want = body[:-INTEGRITY_BYTES], int.from_bytes(body[-INTEGRITY_BYTES:], "big")
    b0, msg_type, tail = first[0] & _CLEAR_SEG_TTL, first[1] & TYPE_MASK, bytes(first[2:HEADER_BYTES])
    ttls = [ttl_guess] if min_ttl <= ttl_guess <= MAX_TTL else []
    ttls += [t for t in range(min_ttl, MAX_TTL + 1) if t != ttl_guess]
    for ttl in ttls:
        for attempt in range(MAX_ATTEMPT + 1):
            header = bytes((b0 | ttl, (attempt << ATTEMPT_SHIFT) | msg_type)) + tail
            if zlib.crc32(payload, zlib.crc32(header)) == want:
                return header + body
    return None


def is_resend_tail(frame: bytes, last: bytes) -> bool:
    """True if `last`, the data of a last segment, ends the logical `frame` sent again with other
    attempt bits (or another TTL): the same header and payload under a CRC-32 recomputed for those.
    An endpoint resend passes; another message under the same (src, seq) almost never does."""
    payload = frame[HEADER_BYTES:-INTEGRITY_BYTES]
    b0, msg_type, tail = frame[0] & ~TTL_MASK & 0xFF, frame[1] & TYPE_MASK, frame[2:HEADER_BYTES]
    for ttl in range(MAX_TTL + 1):
        for attempt in range(MAX_ATTEMPT + 1):
            header = bytes((b0 | ttl, (attempt << ATTEMPT_SHIFT) | msg_type)) + tail
            crc = zlib.crc32(payload, zlib.crc32(header)).to_bytes(INTEGRITY_BYTES, "big")
            if (payload + crc).endswith(last):
                return True
    return False
