"""MeshNode's API: what send() accepts, Transmission metadata, ordering, events and stats."""

from __future__ import annotations

import dataclasses
import math

import pytest

from rescuemesh.mesh import (
    FrameDelivered,
    MeshConfig,
    MeshEvent,
    MeshNode,
    MeshStats,
    NeighbourFound,
    NeighbourLost,
    TransferComplete,
    TransferFailed,
    Transmission,
)
from rescuemesh.mesh.frames import with_ttl
from rescuemesh.mesh.segments import make_segment
from rescuemesh.protocol import MessageType

from .chain import frame as raw_frame
from .frames import data, heartbeat, stop


@pytest.mark.parametrize(
    "bad, match",
    [
        (b"", "at least 10"),
        (stop(1, 2, 1)[:-1] + b"\x00", "CRC"),
        (bytes((0x87,)) + stop(1, 2, 1)[1:], "version"),
        (raw_frame(1, 2, 1, bytes(8183)), "at most 8192"),
        (raw_frame(1, 2, 1, bytes(20), flags=1), "SEG"),
        (raw_frame(1, 2, 1, bytes(2), flags=2), "AUTH"),
        (stop(3, 2, 1), "frame from 3"),
        (raw_frame(255, 2, 1, b""), "255"),
    ],
)
def test_send_refuses_what_it_cannot_send(bad, match):
    with pytest.raises(ValueError, match=match):
        MeshNode(1).send(bad, 0.0)


def test_the_largest_logical_frame_is_accepted():
    node = MeshNode(1)
    node.send(data(1, 2, seq=1, size=8192), 0.0)
    assert node.transmissions(0.0)[0].segments == 512


@pytest.mark.parametrize("address", [-1, 255, 1.0, None])
def test_address_must_be_a_robot_address(address):
    with pytest.raises(ValueError):
        MeshNode(address)


@pytest.mark.parametrize("delay", [-0.001, math.nan, math.inf])
def test_a_bad_relay_delay_is_a_caller_bug(delay):
    with pytest.raises(ValueError, match="relay_delay_s"):
        MeshNode(1).receive(stop(2, 3, 1), 0.0, relay_delay_s=delay)


def test_a_control_frame_leaves_at_once_with_its_metadata():
    node = MeshNode(1)
    frame = stop(1, 2, seq=9)
    node.send(frame, 1.5)
    assert node.get_timer() == 1.5
    assert node.transmissions(1.5) == [Transmission(frame, 1, 2, MessageType.STOP, 9, 7, False, None, None)]
    assert node.get_timer() is None and node.stats.sent == 1 and node.stats.transmitted == 1


def test_a_relayed_segment_carries_its_index_and_count():
    node = MeshNode(5)
    segment = make_segment(data(1, 2, seq=3, size=60), 2, 1)
    node.receive(segment, 0.0, relay_delay_s=0.01)
    [tx] = node.transmissions(0.01)
    assert (tx.src, tx.dst, tx.seq, tx.ttl, tx.relayed, tx.segment, tx.segments) == (1, 2, 3, 6, True, 2, 4)
    assert tx.data == with_ttl(segment, 6) and tx.msg_type == MessageType.DATA


def test_transmissions_come_out_by_due_time():
    node = MeshNode(1, MeshConfig(relay_pace_s=0.0, heartbeat_relay_delay_scale=1.0))  # unpaced, heartbeats not held back
    node.receive(heartbeat(2, seq=1), 0.0, relay_delay_s=0.02)  # relayed copy due at 0.02
    node.send(stop(1, 3, seq=1), 0.01)
    assert node.transmissions(0.015)[0].msg_type == MessageType.STOP
    assert [t.relayed for t in node.transmissions(0.02)] == [True]


def test_frames_for_us_are_delivered_as_received_with_hops_and_direct_rssi():
    node = MeshNode(1)
    relayed_copy = with_ttl(stop(2, 1, seq=4), 5)
    node.receive(relayed_copy, 2.0, rssi_dbm=-70.0)
    events = list(iter(node.next_event, None))
    assert events == [NeighbourFound(2, 3, 2.0), FrameDelivered(relayed_copy, 2, 3, None, 2.0)]
    node.receive(stop(3, 1, seq=4), 2.5, rssi_dbm=-70.0)
    assert node.next_event() == NeighbourFound(3, 1, 2.5)
    assert node.next_event().rssi_dbm == -70.0


def test_segment_acks_for_us_are_consumed_not_delivered():
    from .test_sar import ack_frame

    node = MeshNode(1)
    node.receive(ack_frame(2, 1, ref_seq=1, base=0, bitmap=0), 0.0)
    assert [type(e) for e in iter(node.next_event, None)] == [NeighbourFound]
    assert node.stats.delivered == 0 and node.stats.acks_received == 1


def test_events_share_one_base_class_and_are_frozen():
    classes = (FrameDelivered, NeighbourFound, NeighbourLost, TransferComplete, TransferFailed)
    for cls in classes:
        assert issubclass(cls, MeshEvent) and cls.__dataclass_params__.frozen
    event = NeighbourFound(2, 1, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        event.hops = 2  # type: ignore[misc]


def test_stats_as_dict_names_every_counter():
    stats = MeshStats().as_dict()
    assert set(stats) == {f.name for f in dataclasses.fields(MeshStats)} and set(stats.values()) == {0}
    for name in ("relayed", "delivered", "dropped_cached", "dropped_own", "dropped_ttl", "dropped_corrupt",
                 "dropped_malformed", "segments_sent", "segments_retransmitted", "transfers_complete",
                 "transfers_failed", "reassemblies_complete", "reassemblies_expired", "acks_sent"):
        assert name in stats


def test_a_fresh_node_has_no_timer_and_no_neighbours():
    node = MeshNode(1, MeshConfig())
    assert node.get_timer() is None and node.neighbours() == [] and node.next_event() is None
    assert node.hops_to(2) is None and not node.is_reachable(2, 0.0)


def test_receive_says_whether_it_accepted_the_frame():
    """True for a frame accepted (something may be due to send); False for one dropped, so that a
    transport can skip asking for transmissions."""
    node = MeshNode(1)
    assert node.receive(stop(2, 3, seq=4), 1.0) is True  # new, for another robot: relayed
    assert [t.relayed for t in node.transmissions(1.0)] == [True]
    assert node.receive(with_ttl(stop(2, 3, seq=4), 5), 1.001) is False  # a copy: cached
    assert node.receive(b"\x00" * 12, 1.002) is False  # malformed
    assert node.receive(stop(1, 3, seq=9), 1.003) is False  # our own, heard back
    assert node.receive(stop(2, 3, seq=4, ttl=1), 1.004) is False  # passing by, TTL < 2
