"""Segmentation and reassembly end to end, and the sender's rounds (theory in mesh/sar.py)."""

from __future__ import annotations

import random

import pytest

from rescuemesh.mesh import FrameDelivered, MeshConfig, MeshNode, TransferComplete, TransferFailed
from rescuemesh.protocol import MessageType, decode_frame
from rescuemesh.protocol.messages import SegmentAck

from .chain import chain
from .frames import data, stop


def only(air, address, cls):
    events = air.of_type(address, cls)
    assert len(events) == 1, events
    return events[0]


def test_a_4_kb_frame_crosses_a_chain_of_3_nodes_intact():
    air = chain(3)
    frame = data(1, 3, seq=5, size=4096)
    air.send(1, frame)
    air.run_until(10.0)
    delivered = only(air, 3, FrameDelivered)
    assert delivered.data == frame and delivered.hops == 2 and delivered.src == 1
    done = only(air, 1, TransferComplete)
    assert (done.dst, done.seq, done.segments) == (3, 5, 256)
    # the last release completes it: ack at once, relayed one relay pace after node 2's last segment
    assert done.now == pytest.approx(255 * 0.02 + MeshConfig().relay_pace_s, abs=1e-6)
    assert air.nodes[2].stats.relayed == 256 + air.nodes[3].stats.acks_sent
    assert air.nodes[1].stats.segments_retransmitted == 0


def test_segments_are_paced_one_per_interval_and_the_last_goes_first():
    air = chain(2)
    air.send(1, data(1, 2, seq=1, size=80))  # 5 segments
    air.run_until(1.0)
    sent = [(round(s.now, 6), s.tx.segment) for s in air.log if s.sender == 1]
    assert sent == [(0.0, 4), (0.02, 0), (0.04, 1), (0.06, 2), (0.08, 3)]
    assert {s.tx.segments for s in air.log if s.sender == 1} == {5}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_30_percent_segment_loss_and_reordering_still_complete(seed):
    rng = random.Random(seed)

    def loss(sender, receiver, tx):  # 30 % of the segments never reach node 3
        return receiver == 3 and tx.segment is not None and rng.random() < 0.3

    arrivals = []

    def relay_delay(receiver, frame):  # 0..50 ms: segments 20 ms apart overtake each other
        if receiver == 3 and frame[0] & 0x10:
            arrivals.append(int.from_bytes(frame[6:9], "big") >> 12)
        return rng.uniform(0.0, 0.05)

    air = chain(3, loss=loss, relay_delay=relay_delay)
    frame = data(1, 3, seq=5, size=4096)
    air.send(1, frame)
    air.run_until(60.0)
    assert only(air, 3, FrameDelivered).data == frame
    assert only(air, 1, TransferComplete).segments == 256
    first_round = arrivals[: 200]
    assert first_round != sorted(first_round)  # reordered indeed
    assert air.nodes[1].stats.segments_retransmitted > 0.3 * 256 * 0.8


@pytest.mark.parametrize("seed", [1, 2])
def test_10_percent_loss_of_every_frame_acks_included_still_completes(seed):
    rng = random.Random(seed)
    air = chain(3, loss=lambda s, r, tx: rng.random() < 0.1, relay_delay=lambda r, f: rng.uniform(0, 0.03))
    frame = data(1, 3, seq=5, size=2048)
    air.send(1, frame)
    air.run_until(60.0)
    assert only(air, 3, FrameDelivered).data == frame
    only(air, 1, TransferComplete)


def test_gives_up_after_max_retransmissions_when_the_receiver_is_gone():
    node = MeshNode(1)
    node.send(data(1, 2, seq=7, size=40), 0.0)  # 3 segments to robot 2, which never answers
    sent, now = [], 0.0
    while (timer := node.get_timer()) is not None:
        now = timer
        node.handle_timer(now)
        sent += [(round(now, 6), tx.segment, tx.data[1] >> 6) for tx in node.transmissions(now)]
    # hops to 2 unknown: wait 0.2 + 0.05 * 7 = 0.55 s after each round; rounds 1-4 are one probe
    assert sent == [(0.0, 2, 0), (0.02, 0, 0), (0.04, 1, 0), (0.59, 0, 1), (1.14, 0, 2), (1.69, 0, 3),
                    (2.24, 0, 0)]
    assert node.next_event() == TransferFailed(2, 7, 0, 3, pytest.approx(2.79))
    assert node.stats.transfers_failed == 1 and node.stats.segments_retransmitted == 4


class Clock:
    """Drives one node alone: each step goes to its next timer and collects what it releases."""

    def __init__(self, node: MeshNode) -> None:
        self.node, self.now, self.released = node, 0.0, []

    def step(self) -> None:
        self.now = self.node.get_timer()
        self.node.handle_timer(self.now)
        self.released += [(round(self.now, 6), tx.segment) for tx in self.node.transmissions(self.now)]

    def receive(self, frame: bytes, now: float) -> None:
        self.now = now
        self.node.receive(frame, now)
        self.node.handle_timer(now)
        self.released += [(round(now, 6), tx.segment) for tx in self.node.transmissions(now)]


def test_a_block_ack_marks_segments_and_later_rounds_resend_only_the_reported_missing():
    clock = Clock(MeshNode(1, MeshConfig(relay=False)))
    clock.node.send(data(1, 2, seq=7, size=6 + 16 * 8), 0.0)  # 8 segments
    while len(clock.released) < 8:
        clock.step()
    assert [i for _, i in clock.released] == [7, 0, 1, 2, 3, 4, 5, 6]
    clock.released.clear()
    clock.receive(ack_frame(src=2, dst=1, ref_seq=7, base=2, bitmap=0b10101), 0.2)  # has 0-2, 4, 6
    while len(clock.released) < 6:
        clock.step()
    # progress while waiting: round 1 at once; no ack for it: round 2 after 0.2 + 0.05 * 1 s
    assert clock.released == [(0.2, 3), (0.22, 5), (0.24, 7), (0.49, 3), (0.51, 5), (0.53, 7)]


def test_a_round_that_made_progress_does_not_use_up_the_budget():
    # this used to count the first round against max_retransmissions when its progress came while
    # it was still being released: a transfer then gave up after 4 silent rounds instead of 1 + 4
    clock = Clock(MeshNode(1, MeshConfig(relay=False)))
    clock.node.send(data(1, 2, seq=7, size=6 + 16 * 8), 0.0)  # 8 segments
    clock.step()
    clock.receive(ack_frame(2, 1, ref_seq=7, base=1, bitmap=0), 0.01)  # progress during round 0
    while clock.node.get_timer() is not None:
        clock.step()
    [failed] = [e for e in iter(clock.node.next_event, None) if type(e) is TransferFailed]
    assert (failed.acked, failed.total) == (1, 8)
    # round 0's deadline starts round 1 for free; then 4 silent rounds use the budget up
    assert clock.node.stats.segments_retransmitted == 5 * 7


def test_with_nothing_known_missing_a_round_is_a_single_probe():
    clock = Clock(MeshNode(1, MeshConfig(relay=False)))
    clock.node.send(data(1, 2, seq=7, size=6 + 16 * 100), 0.0)  # 100 segments
    while len(clock.released) < 100:
        clock.step()
    clock.released.clear()
    clock.receive(ack_frame(2, 1, ref_seq=7, base=10, bitmap=(1 << 48) - 1), 2.0)  # 0..57 arrived
    # 58..99 are unknown, not reported missing: one probe draws the next ack
    clock.step()  # the pacer's next slot (2.0 s plus float dust)
    assert clock.released == [(2.0, 58)]
    clock.step()  # no ack for it: the same probe, 0.2 + 0.05 * 1 s later
    assert clock.released == [(2.0, 58), (2.25, 58)]
    assert clock.node.stats.segments_retransmitted == 2


def ack_frame(src: int, dst: int, ref_seq: int, base: int, bitmap: int, seq: int = 0) -> bytes:
    from rescuemesh.protocol import encode_frame
    from rescuemesh.protocol.codec import FrameFlags, Header

    header = Header(1, FrameFlags.NONE, 7, 0, MessageType.SEGMENT_ACK, src, dst, seq)
    return encode_frame(header, SegmentAck(ref_seq, base, bitmap))


def test_an_ack_for_another_transfer_or_beyond_its_segments_is_ignored():
    node = MeshNode(1, MeshConfig(relay=False))
    node.send(data(1, 2, seq=7, size=40), 0.0)
    node.receive(ack_frame(2, 1, ref_seq=8, base=3, bitmap=0), 0.01)  # another seq
    node.receive(ack_frame(3, 1, ref_seq=7, base=3, bitmap=0, seq=1), 0.01)  # another robot
    node.receive(ack_frame(2, 1, ref_seq=7, base=4, bitmap=0, seq=2), 0.01)  # 4 > 3 segments
    assert node.stats.acks_unmatched == 3
    assert [e for e in iter(node.next_event, None) if type(e) in (TransferComplete, TransferFailed)] == []


def test_transfers_to_one_destination_queue_and_to_two_destinations_interleave():
    # this used to give the pacer back to the transfer that had just released (1, 1, 3, 1, ...)
    air = chain(3)
    air.send(2, data(2, 1, seq=1, size=38))  # 2 segments to 1
    air.send(2, data(2, 1, seq=2, size=38))  # waits for the first
    air.send(2, data(2, 3, seq=3, size=38))  # another destination: interleaves
    air.run_until(5.0)
    order = [(s.tx.dst, s.tx.seq) for s in air.log if s.sender == 2 and s.tx.segment is not None]
    assert order[:4] == [(1, 1), (3, 3), (1, 1), (3, 3)]
    assert [e.seq for e in air.of_type(2, TransferComplete)] == [1, 3, 2]
    assert air.nodes[2].stats.transfers_queued == 1
    assert [len(air.of_type(a, FrameDelivered)) for a in (1, 3)] == [2, 1]


def test_a_control_frame_goes_out_between_segments_at_once():
    air = chain(2)
    air.send(1, data(1, 2, seq=1, size=200))
    air.run_until(0.05)
    air.send(1, stop(1, 2, seq=2))
    air.run_until(0.1)
    times = [(round(s.now, 6), s.tx.msg_type) for s in air.log if s.sender == 1]
    assert (0.05, MessageType.STOP) in times
    assert [t for t, m in times if m == MessageType.DATA][:4] == [0.0, 0.02, 0.04, 0.06]


def test_an_endpoint_resend_during_a_transfer_is_absorbed():
    air = chain(2)
    air.send(1, data(1, 2, seq=1, size=200))
    air.run_until(0.1)
    air.send(1, data(1, 2, seq=1, size=200, attempt=1))
    air.run_until(5.0)
    assert air.nodes[1].stats.resends_absorbed == 1
    assert len(air.of_type(1, TransferComplete)) == 1 and len(air.of_type(2, FrameDelivered)) == 1


def test_an_endpoint_resend_after_completion_is_delivered_again_from_its_last_segment():
    # this used to miss the resend when the frame's CRC straddled the last two segments (200 bytes:
    # the last segment holds 2 of its 4 bytes), because the frame was rebuilt from the new tail
    air = chain(3)
    first, resend = data(1, 3, seq=1, size=200), data(1, 3, seq=1, size=200, attempt=1)
    air.send(1, first)
    air.run_until(5.0)
    air.send(1, resend)  # the Confirm was lost: the endpoint sends the frame again
    air.run_until(10.0)
    assert [e.data for e in air.of_type(3, FrameDelivered)] == [first, first]  # the endpoint dedupes
    assert air.nodes[3].stats.redeliveries == 1
    assert len(air.of_type(1, TransferComplete)) == 2
    resend_segments = [s for s in air.log if s.sender == 1 and s.now >= 5.0 and s.tx.segment is not None]
    assert resend_segments[0].tx.segment == 12  # the last one, first


def test_send_refuses_a_segmented_broadcast():
    from .chain import frame

    with pytest.raises(ValueError, match="unicast"):
        MeshNode(1).send(frame(1, 255, 1, bytes(30)), 0.0)


def test_segment_acks_carry_the_nodes_own_counter():
    air = chain(2)
    air.send(1, data(1, 2, seq=1, size=200))
    air.run_until(5.0)
    acks = [s.tx for s in air.log if s.sender == 2]
    assert [a.seq for a in acks] == list(range(len(acks))) and len(acks) >= 2
    assert all(decode_frame(a.data)[1].ref_seq == 1 for a in acks)


def test_an_endpoint_resend_while_the_transfer_waits_starts_its_next_round_at_once():
    # robot 2 never answers and its distance is unknown, so a round waits 0.55 s; the endpoint resends
    # after 0.18 and 0.36 s (its Confirm timer), and each resend puts the frame on the air again
    node = MeshNode(1)
    node.send(data(1, 2, seq=7, size=22), 0.0)  # one segment
    released = [(0.0, tx.segment) for tx in node.transmissions(0.0)]
    for resend_at, attempt in ((0.18, 1), (0.36, 2)):
        node.send(data(1, 2, seq=7, size=22, attempt=attempt), resend_at)
        released += [(resend_at, tx.segment) for tx in node.transmissions(resend_at)]
    assert released == [(0.0, 0), (0.18, 0), (0.36, 0)]
    assert node.stats.resends_absorbed == 2 and node.stats.segments_retransmitted == 2
    assert node.get_timer() == pytest.approx(0.36 + 0.55)  # the wait starts again from the last round


def test_a_resend_while_segments_are_still_being_released_changes_nothing():
    node = MeshNode(1)
    node.send(data(1, 2, seq=7, size=80), 0.0)  # 5 segments, one per 20 ms
    node.transmissions(0.0)
    node.send(data(1, 2, seq=7, size=80, attempt=1), 0.01)
    assert node.transmissions(0.01) == [] and node.stats.segments_retransmitted == 0


def test_abandoned_transfers_end_without_an_event_and_the_next_one_starts():
    node = MeshNode(1)
    node.send(data(1, 2, seq=7, size=22), 0.0)
    node.send(data(1, 2, seq=8, size=22), 0.0)  # queued behind seq 7
    node.send(data(1, 2, seq=9, size=22), 0.0)  # queued behind seq 8
    node.transmissions(0.0)
    node.abandon_transfers(lambda dst, seq: seq == 9, 0.1)  # 7 given up, 8 confirmed meanwhile
    assert node.stats.transfers_abandoned == 2
    assert [(tx.seq, tx.segment) for tx in node.transmissions(0.1)] == [(9, 0)]
    assert not any(type(e) in (TransferComplete, TransferFailed) for e in iter(node.next_event, None))
    node.abandon_transfers(lambda dst, seq: False, 0.2)
    assert node.get_timer() is None and node.transmissions(0.2) == []
