"""The receiving half of SAR (mesh/reassembly.py): acks, timers, completed memory, bad segments."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rescuemesh.mesh import FrameDelivered, MeshConfig, MeshNode
from rescuemesh.mesh.frames import with_ttl
from rescuemesh.mesh.segments import make_segment, segment_count
from rescuemesh.protocol import MessageType, decode_frame
from rescuemesh.protocol.messages import SegmentAck

from .chain import frame as raw_frame
from .frames import data


class Receiver:
    """Node 1 alone (no relaying), fed segments of frames from robot 2 that crossed 2 hops."""

    def __init__(self, **config) -> None:
        self.node = MeshNode(1, MeshConfig(relay=False, **config))
        self.acks: list[tuple[float, SegmentAck]] = []
        self.delivered: list[FrameDelivered] = []

    def feed(self, frame: bytes, indices, now: float, round_: int = 0, ttl: int = 6) -> None:
        for i in indices:
            self.node.receive(with_ttl(make_segment(frame, i, round_), ttl), now)
        self.collect(now)

    def collect(self, now: float) -> None:
        for tx in self.node.transmissions(now):
            assert tx.msg_type == MessageType.SEGMENT_ACK and tx.dst == 2
            self.acks.append((now, decode_frame(tx.data)[1]))
        for event in iter(self.node.next_event, None):
            if type(event) is FrameDelivered:
                self.delivered.append(event)

    def run_until(self, t: float) -> None:
        while (timer := self.node.get_timer()) is not None and timer <= t:
            self.node.handle_timer(timer)
            self.collect(timer)


MESSAGE = data(2, 1, seq=40, size=6 + 16 * 8)  # 8 segments


def test_the_ack_timer_sends_base_and_bitmap_150_plus_50_ms_per_hop_after_the_first_segment():
    rx = Receiver()
    rx.feed(MESSAGE, [0, 1, 3], now=0.0)
    rx.feed(MESSAGE, [5], now=0.1)  # the timer is running: not restarted
    assert rx.node.get_timer() == pytest.approx(0.15 + 0.05 * 2)  # 2 hops: TTL 6 of init_ttl 7
    rx.run_until(1.0)
    assert rx.acks == [(pytest.approx(0.25), SegmentAck(40, 2, 0b1010))]


def test_the_completing_segment_delivers_the_exact_frame_and_acks_at_once():
    rx = Receiver()
    rx.feed(MESSAGE, [7, 0, 1, 2], now=0.0)
    rx.feed(MESSAGE, [3, 4, 5, 6], now=0.05)
    [event] = rx.delivered
    assert event.data == MESSAGE and (event.src, event.hops, event.rssi_dbm, event.now) == (2, 2, None, 0.05)
    assert rx.acks == [(0.05, SegmentAck(40, 8, 0))]
    assert rx.node.stats.reassemblies_complete == 1
    rx.run_until(1.0)
    assert len(rx.acks) == 1  # the pending ack timer went with the reassembly


def test_a_duplicate_segment_draws_an_ack_at_once_at_most_one_per_60_ms():
    rx = Receiver()
    rx.feed(MESSAGE, [0, 1], now=0.0)
    rx.run_until(0.3)  # the ack timer's ack (0.25 s)
    rx.feed(MESSAGE, [0], now=0.5, round_=1)  # the sender did not hear it
    rx.feed(MESSAGE, [1], now=0.52, round_=1)  # too soon for another
    rx.feed(MESSAGE, [1], now=0.56, round_=2)
    assert [t for t, _ in rx.acks] == [pytest.approx(0.25), 0.5, 0.56]
    assert rx.node.stats.segments_duplicate == 3


def test_a_late_duplicate_segment_after_completion_gets_the_complete_ack_and_no_second_delivery():
    rx = Receiver()
    rx.feed(MESSAGE, range(8), now=0.0)
    rx.feed(MESSAGE, [3], now=0.01, round_=1)  # within 60 ms of the final ack: nothing
    rx.feed(MESSAGE, [3], now=1.0, round_=2)  # the final ack was lost: the sender retries
    assert len(rx.delivered) == 1
    assert rx.acks == [(0.0, SegmentAck(40, 8, 0)), (1.0, SegmentAck(40, 8, 0))]
    assert rx.node.stats.segments_late == 2


def test_a_completed_message_is_forgotten_after_the_incomplete_timeout():
    rx = Receiver()
    rx.feed(MESSAGE, range(8), now=0.0)
    rx.run_until(10.0)
    rx.feed(MESSAGE, [3], now=10.5, round_=1)  # now the start of a new reassembly
    assert rx.node.stats.segments_late == 0 and rx.node.stats.segments_received == 9
    assert len(rx.delivered) == 1


def test_the_incomplete_timer_discards_10_s_after_the_last_new_segment():
    rx = Receiver()
    rx.feed(MESSAGE, [0, 1], now=0.0)
    rx.feed(MESSAGE, [2], now=4.0)  # restarts it
    rx.feed(MESSAGE, [2], now=6.0, round_=1)  # a duplicate does not
    rx.run_until(13.999)
    assert rx.node.stats.reassemblies_expired == 0
    rx.run_until(14.0)
    assert rx.node.stats.reassemblies_expired == 1
    assert rx.node.get_timer() == 6.0 + 60.0  # no SAR timer left behind: only forgetting robot 2
    rx.feed(MESSAGE, [3, 4, 5, 6, 7], now=20.0)  # the rest alone cannot complete it
    assert rx.delivered == [] and rx.node.stats.reassemblies_complete == 0


def test_reassemblies_are_bounded_per_source_and_in_total():
    rx = Receiver(max_reassemblies=3, max_reassemblies_per_source=2)
    for seq in (1, 2, 3):
        rx.feed(data(2, 1, seq=seq, size=38), [0], now=0.0)  # 2 segments each
    assert rx.node.stats.reassemblies_rejected == 1
    for src in (3, 4):
        rx.feed(data(src, 1, seq=1, size=38), [0], now=0.0)
    assert rx.node.stats.reassemblies_rejected == 2  # 3 in total already
    rx.feed(data(2, 1, seq=1, size=38), [1], now=0.1)  # the admitted ones go on
    assert len(rx.delivered) == 1


def test_segments_of_two_messages_under_one_seq_are_not_delivered():
    # a restarted source reusing a seq within the incomplete timeout: the frame's own CRC-32 tells
    rx = Receiver()
    other = raw_frame(2, 1, 40, bytes(len(MESSAGE) - 10), msg_type=36)  # same header, other payload
    rx.feed(MESSAGE, [0, 1, 2, 3], now=0.0)
    rx.feed(other, [4, 5, 6, 7], now=0.0)
    assert rx.delivered == [] and rx.node.stats.reassemblies_corrupt == 1


def seg(seg_o: int, seg_n: int, chunk: bytes, *, dst: int = 1, seq: int = 40, msg_type: int = 36) -> bytes:
    return raw_frame(2, dst, seq, ((seg_o << 12) | seg_n).to_bytes(3, "big") + chunk, flags=1, msg_type=msg_type)


@pytest.mark.parametrize(
    "bad",
    [
        seg(2, 1, bytes(16)),  # SegO > SegN
        seg(0, 600, bytes(16)),  # too many segments
        seg(0, 7, bytes(10)),  # not the last, short
        seg(0, 0, bytes(2)),  # a frame shorter than 10 bytes
        seg(0, 9, bytes(16)),  # SegN differs from the reassembly's (7)
        seg(1, 7, bytes(16), msg_type=7),  # type differs from the reassembly's
        seg(0, 0, bytes(16), dst=255),  # segmented broadcast
        raw_frame(2, 1, 3, b"\x00\x00\xff\xff" + bytes(6), msg_type=35),  # a SegmentAck, base 65535
        raw_frame(2, 1, 3, bytes(9), msg_type=35),  # a SegmentAck one byte short
        raw_frame(2, 1, 3, bytes(24), flags=1),  # a segment frame of 34 bytes
        raw_frame(2, 1, 3, bytes(11)),  # an unsegmented frame of 21 bytes on the air
    ],
)
def test_malformed_segments_are_dropped_and_counted_never_raised(bad):
    rx = Receiver()
    rx.feed(MESSAGE, [0], now=0.0)
    before = rx.node.stats.dropped_malformed
    rx.node.receive(bad, 0.01)
    rx.collect(0.01)
    assert rx.node.stats.dropped_malformed == before + 1
    assert rx.delivered == []


@given(st.binary(max_size=40))
def test_arbitrary_bytes_never_raise(blob):
    node = MeshNode(1)
    node.receive(blob, 0.0)
    node.handle_timer(20.0)


@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 0x3F), st.integers(0, 15),
                          st.integers(0, 1), st.binary(min_size=4, max_size=23)), max_size=30))
@settings(max_examples=150)
def test_arbitrary_frames_under_a_valid_crc_never_raise(frames):
    node = MeshNode(1, MeshConfig(max_reassemblies=2, max_reassemblies_per_source=1))
    for i, (flags, msg_type, ttl, dst_is_us, body) in enumerate(frames):
        dst = 1 if dst_is_us else 255
        node.receive(raw_frame(2 + i % 3, dst, i % 4, body, ttl=ttl, msg_type=msg_type, flags=flags), i * 0.01)
        node.handle_timer(i * 0.01)
        node.transmissions(i * 0.01)
    node.handle_timer(30.0)
    list(iter(node.next_event, None))


@given(st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40), st.integers(1, 16)), max_size=40))
def test_arbitrary_segment_headers_never_raise(segments):
    node = MeshNode(1, MeshConfig(relay=False))
    for i, (seg_o, seg_n, size) in enumerate(segments):
        node.receive(seg(seg_o, seg_n, bytes(range(size))), i * 0.01)
        node.handle_timer(i * 0.01)
    node.handle_timer(30.0)
    node.transmissions(30.0)
    assert node.get_timer() is None or node.get_timer() > 30.0  # every SAR timer has run out


def test_segment_count_matches_message():
    assert segment_count(len(MESSAGE)) == 8


def test_another_message_reusing_a_completed_seq_is_reassembled_not_taken_for_a_resend():
    # a source that restarted within the incomplete timeout and reuses seq 40 for another frame
    # of the same length: its last segment (sent first) does not fit the completed frame
    rx = Receiver()
    rx.feed(MESSAGE, range(8), now=0.0)
    other = raw_frame(2, 1, 40, bytes(len(MESSAGE) - 10), msg_type=36)
    rx.feed(other, [7, *range(7)], now=1.0)
    assert [e.data for e in rx.delivered] == [MESSAGE, other]
    assert rx.node.stats.redeliveries == 0


def test_an_endpoint_resend_of_a_completed_frame_is_delivered_again_once():
    rx = Receiver()
    rx.feed(MESSAGE, range(8), now=0.0)
    resend = data(2, 1, seq=40, size=len(MESSAGE), attempt=2)
    rx.feed(resend, [7], now=1.0)
    rx.feed(resend, [7], now=1.5, round_=1)  # the same resend's segment again: no third delivery
    assert [e.data for e in rx.delivered] == [MESSAGE, MESSAGE]
    assert rx.node.stats.redeliveries == 1
