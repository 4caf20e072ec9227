"""Segment frames byte by byte (docs/mesh.md section 6): split, parse, block ack, rebuild."""

from __future__ import annotations

import re
import zlib
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rescuemesh.mesh import segments as segments_module
from rescuemesh.mesh.events import FrameDelivered
from rescuemesh.mesh.frames import read_on_air
from rescuemesh.mesh.node import MeshNode
from rescuemesh.mesh.segments import (
    MAX_SEGMENTS,
    Segment,
    acked_indices,
    block_ack,
    make_segment,
    parse_segment,
    rebuild_frame,
    segment_count,
)
from rescuemesh.protocol import decode_frame
from rescuemesh.protocol.errors import MalformedPayload

from .chain import frame as raw_frame
from .frames import data, stop

DOC = Path(__file__).resolve().parents[2] / "docs" / "mesh.md"


def segments_of(frame: bytes, round_: int = 0) -> list[bytes]:
    return [make_segment(frame, i, round_) for i in range(segment_count(len(frame)))]


def test_docs_worked_example():
    text = DOC.read_text(encoding="utf-8")
    block = text.split("<!-- worked-example -->")[1].split("<!-- /worked-example -->")[0]
    logical, *segments = [bytes.fromhex(b) for b in re.findall(r"```text\n(.*?)\n```", block, re.S)]
    header, message = decode_frame(logical)
    assert (header.src, header.dst, header.seq, header.ttl) == (2, 1, 11, 7)
    assert message.data == b"rescuemesh scan!ranges"
    assert segments == segments_of(logical)
    assert len(segments) == 2 and [len(s) for s in segments] == [29, 26]
    body = b"".join(parse_segment(s).data for s in segments)
    assert rebuild_frame(segments[1], body, 7, 7) == logical


@pytest.mark.parametrize("size, count", [(21, 1), (22, 1), (23, 2), (38, 2), (39, 3), (8192, 512)])
def test_segment_count(size, count):
    assert segment_count(size) == count


def test_segments_carry_the_header_with_seg_and_round_and_16_bytes_each():
    frame = data(1, 2, seq=300, size=100)
    segs = segments_of(frame, round_=2)
    assert len(segs) == 6 and all(len(s) == 29 for s in segs[:-1]) and len(segs[-1]) == 9 + (94 - 80) + 4
    for i, seg in enumerate(segs):
        view = read_on_air(seg)  # a valid frame on the air: 29 bytes, CRC right
        assert seg[0] == frame[0] | 0x10 and seg[1] == (2 << 6) | frame[1] & 0x3F
        assert seg[2:6] == frame[2:6] and view.seq == 300
        assert parse_segment(seg) == Segment(i, 5, 2, 36, frame[6 + 16 * i : 6 + 16 * (i + 1)])


def test_the_round_travels_mod_4():
    frame = data(1, 2, seq=1, size=40)
    assert make_segment(frame, 0, 5) == make_segment(frame, 0, 1)


def test_largest_frame_uses_segn_511():
    frame = data(1, 2, seq=1, size=8192)
    last = make_segment(frame, 511, 0)
    assert parse_segment(last).seg_n == 511 == MAX_SEGMENTS - 1
    assert len(last) == 9 + 10 + 4  # 8186 = 511 * 16 + 10


def seg(seg_o: int, seg_n: int, chunk: bytes, src: int = 1, dst: int = 2, seq: int = 1) -> bytes:
    header = ((seg_o << 12) | seg_n).to_bytes(3, "big")
    return raw_frame(src, dst, seq, header + chunk, flags=1)


@pytest.mark.parametrize(
    "frame, reason",
    [
        (seg(2, 1, bytes(16)), "SegO > SegN"),
        (seg(0, 512, bytes(16)), "more than 8192 bytes"),
        (seg(0, 3, bytes(15)), "not the last, short"),
        (seg(0, 0, bytes(3)), "a frame shorter than 10 bytes"),
        (seg(511, 511, bytes(11)), "a frame longer than 8192 bytes"),
        (raw_frame(1, 2, 1, b"\x00\x00", flags=1), "no data byte"),
    ],
)
def test_malformed_segments_raise_malformed_payload(frame, reason):
    with pytest.raises(MalformedPayload):
        parse_segment(frame)


def test_the_smallest_legal_segmented_frame_parses():
    # SegN 0 with 4 data bytes: a 10-byte logical frame (header + CRC), odd but legal
    assert parse_segment(seg(0, 0, bytes(4))).seg_n == 0


def held(n: int, indices) -> list[bytes | None]:
    pieces: list[bytes | None] = [None] * n
    for i in indices:
        pieces[i] = b"x"
    return pieces


@pytest.mark.parametrize(
    "n, indices, base, bitmap",
    [
        (6, [0, 1, 3, 5], 2, 0b1010),
        (6, [], 0, 0),
        (6, range(6), 6, 0),
        (100, [0, *range(2, 100)], 1, (1 << 48) - 2),  # window: segments 1..48 only
        (60, [59], 0, 0),  # beyond the 48-bit window: not reported
    ],
)
def test_block_ack(n, indices, base, bitmap):
    assert block_ack(held(n, indices), 0) == (base, bitmap)


def test_acked_indices_inverts_block_ack():
    pieces = held(80, [0, 1, 2, 4, 7, 40, 50, 79])
    base, bitmap = block_ack(pieces, 0)
    assert acked_indices(base, bitmap, 80) == [0, 1, 2, 4, 7, 40, 50]  # 79 is beyond base + 47
    assert acked_indices(3, 1 << 47 | 1, 10) == [0, 1, 2, 3]  # bits beyond the message ignored


@pytest.mark.parametrize("ttl_sent, attempt", [(7, 0), (7, 3), (3, 1), (15, 2), (0, 0)])
def test_rebuild_recovers_the_original_ttl_and_attempt_bits(ttl_sent, attempt):
    frame = data(1, 2, seq=9, size=60, ttl=ttl_sent, attempt=attempt)
    segs = segments_of(frame, round_=1)
    body = b"".join(parse_segment(s).data for s in segs)
    lowered = bytes((segs[0][0] & 0xF0 | max(0, ttl_sent - 2),)) + segs[0][1:]  # heard 2 relays away
    assert rebuild_frame(lowered, body, 7, max(0, ttl_sent - 2)) == frame


def test_rebuild_refuses_a_body_that_is_not_the_frame():
    frame = data(1, 2, seq=9, size=60)
    body = bytearray(b"".join(parse_segment(s).data for s in segments_of(frame)))
    body[5] ^= 0xFF  # one segment from another message
    assert rebuild_frame(make_segment(frame, 0, 0), bytes(body), 7, 0) is None


@given(st.binary(min_size=15, max_size=600), st.integers(0, 15), st.integers(0, 3), st.integers(0, 3))
def test_split_and_rebuild_round_trip(payload, ttl, attempt, round_):
    frame = raw_frame(3, 4, 77, payload, ttl=ttl, attempt=attempt)
    segs = segments_of(frame, round_)
    assert all(14 <= len(s) <= 29 for s in segs)
    body = b"".join(parse_segment(s).data for s in segs)
    assert rebuild_frame(segs[-1], body, 7, ttl) == frame


# --- docs/mesh.md section 6: the rules issue 23 settled ---------------------------------------------


def _section_6() -> str:
    text = DOC.read_text(encoding="utf-8")
    return " ".join(text[text.index("## 6. Segment frames"):text.index("## 7. ")].split())


class _RecordingZlib:
    """Stands in for zlib inside segments.py: records each header rebuild_frame tries."""

    def __init__(self) -> None:
        self.tried: list[tuple[int, int]] = []

    def crc32(self, data: bytes, value: int = 0) -> int:
        if len(data) == 6 and value == 0:  # a candidate header: (TTL, attempt)
            self.tried.append((data[0] & 0x0F, data[1] >> 6))
        return zlib.crc32(data, value)


@pytest.mark.parametrize("g, m", [(7, 5), (3, 5), (7, 7), (15, 15), (0, 0), (9, 2)])
def test_rebuild_tries_the_candidates_in_the_documented_order(monkeypatch, g, m):
    rule = ("The candidates, in this order, are: TTL g if m ≤ g ≤ 15; then TTL m, m + 1, .. 15, "
            "skipping g; and for each TTL, attempt 0, 1, 2, 3.")
    assert rule in _section_6()
    ttls = ([g] if m <= g <= 15 else []) + [t for t in range(m, 16) if t != g]
    documented = [(ttl, attempt) for ttl in ttls for attempt in range(4)]
    frame = data(1, 2, seq=9, size=40)
    body = frame[6:-4] + bytes(4)  # a CRC no candidate gives: every candidate is tried
    recorder = _RecordingZlib()
    monkeypatch.setattr(segments_module, "zlib", recorder)
    assert rebuild_frame(make_segment(frame, 0, 0), body, g, m) is None
    assert recorder.tried == documented


@pytest.mark.parametrize("size", [10, 13, 20])
def test_a_segmented_logical_frame_of_10_to_20_bytes_is_tolerated(size):
    assert ("a frame of 10..20 bytes always goes unsegmented. A receiver does not check that: segments "
            "that rebuild a logical frame of 10..20 bytes are reassembled and delivered") in _section_6()
    frame = stop(1, 2, seq=4) if size == 10 else data(1, 2, seq=4, size=size)
    node = MeshNode(2)
    for segment in segments_of(frame):
        node.receive(segment, 0.0)
    delivered = [e for e in iter(node.next_event, None) if isinstance(e, FrameDelivered)]
    assert [e.data for e in delivered] == [frame]
    assert node.stats.dropped_malformed == 0
