"""Managed flooding (Bluetooth Mesh Profile 1.0, 3.4.6): relaying over a chain of sans-IO nodes."""

from __future__ import annotations

from rescuemesh.mesh import FrameDelivered, MeshConfig
from rescuemesh.protocol import decode_frame

from .chain import chain, mesh
from .frames import heartbeat, stop


def delivered(air, address):
    return air.of_type(address, FrameDelivered)


def test_a_frame_from_node_1_reaches_node_6_five_hops_away():
    air = chain(6)
    frame = stop(1, 6, seq=1)
    air.send(1, frame)
    [event] = delivered(air, 6)
    assert event.src == 1 and event.hops == 5
    assert event.data[0] & 0x0F == 7 - 4  # TTL as received: four relays took one each
    assert decode_frame(event.data)[1] == decode_frame(frame)[1]
    assert [air.nodes[a].stats.relayed for a in range(1, 7)] == [0, 1, 1, 1, 1, 0]
    assert all(not delivered(air, a) for a in range(1, 6))  # unicast: only node 6 delivers


def test_a_relayed_frame_differs_only_in_ttl_and_crc():
    air = chain(3)
    frame = stop(1, 3, seq=1)
    air.send(1, frame)
    [relayed] = air.sent_by(2)
    assert relayed.relayed and relayed.ttl == 6
    assert relayed.data[0] == (frame[0] & 0xF0) | 6 and relayed.data[1:-4] == frame[1:-4]
    decode_frame(relayed.data)  # CRC recomputed: a valid frame


def test_initial_ttl_3_reaches_exactly_3_hops():
    air = chain(6)
    air.send(1, heartbeat(1, seq=1, ttl=3))
    assert [len(delivered(air, a)) for a in range(2, 7)] == [1, 1, 1, 0, 0]
    assert delivered(air, 4)[0].hops == 3
    assert air.nodes[4].stats.dropped_ttl == 1 and air.nodes[4].stats.relayed == 0
    assert not air.sent_by(4) and not air.sent_by(5)


def test_a_node_hearing_the_same_frame_from_two_relays_relays_and_delivers_it_once():
    # 1 reaches 4 through 2 and through 3; 4 relays to 5
    air = mesh(range(1, 6), [(1, 2), (1, 3), (2, 4), (3, 4), (4, 5)])
    air.send(1, stop(1, 5, seq=1))
    assert air.nodes[4].stats.relayed == 1
    assert air.nodes[4].stats.dropped_cached == 1
    assert not delivered(air, 4) and len(delivered(air, 5)) == 1


def test_a_resend_with_new_attempt_bits_is_relayed_again_but_the_same_bytes_are_not():
    air = chain(3)
    air.send(1, stop(1, 3, seq=1))
    air.send(1, stop(1, 3, seq=1))  # the same bytes again: cached at node 2
    assert air.nodes[2].stats.relayed == 1 and air.nodes[2].stats.dropped_cached == 1
    air.send(1, stop(1, 3, seq=1, attempt=1))  # the endpoint's resend: a new frame for the cache
    air.run_until(0.1)  # node 2 relays it one relay pace after the first
    assert air.nodes[2].stats.relayed == 2
    assert [e.data[1] >> 6 for e in delivered(air, 3)] == [0, 1]  # the endpoint dedupes


def test_relay_off_on_the_middle_node_cuts_the_chain():
    air = chain(5, configs={3: MeshConfig(relay=False)})
    air.send(1, stop(1, 5, seq=1))
    assert not delivered(air, 5)
    assert air.nodes[3].stats.relayed == 0 and not air.sent_by(3)
    assert air.nodes[4].stats.received == 0
    air.send(1, stop(1, 3, seq=2))  # the relay feature does not affect delivery to node 3
    air.run_until(0.1)  # node 2 relays it one relay pace after the first
    assert len(delivered(air, 3)) == 1


def test_own_frames_heard_back_are_dropped_not_relayed():
    air = chain(2)
    air.send(1, heartbeat(1, seq=1))
    assert air.nodes[2].stats.relayed == 1  # broadcast: delivered and relayed
    assert air.nodes[1].stats.dropped_own == 1
    assert len(air.sent_by(1)) == 1 and not delivered(air, 1)


def test_corrupt_frames_are_dropped_not_relayed_and_not_heard():
    air = chain(3)
    frame = bytearray(stop(1, 3, seq=1))
    frame[6 - 1] ^= 0x01
    air.inject(2, bytes(frame))
    assert air.nodes[2].stats.dropped_corrupt == 1
    assert not air.log and air.nodes[3].stats.received == 0
    assert air.nodes[2].neighbours() == []


def test_the_relay_delay_passed_in_is_honoured():
    air = chain(3, relay_delay=lambda address, data: 0.015)
    air.send(1, stop(1, 3, seq=1))
    node2 = air.nodes[2]
    assert node2.get_timer() == 0.015
    assert node2.transmissions(0.0149) == []
    air.run_until(0.1)
    [relay] = [s for s in air.log if s.sender == 2]
    assert relay.now == 0.015
    assert delivered(air, 3)[0].now == 0.015


def test_unknown_message_types_are_relayed_because_relays_read_the_header_only():
    from .chain import frame

    air = chain(3)
    air.inject(1, frame(9, 3, 1, b"\x00" * 4, msg_type=60))  # type 60 does not exist (yet)
    assert air.nodes[2].stats.relayed == 1
    assert len(delivered(air, 3)) == 1  # and delivered: the endpoint rejects it, not the mesh


def test_relay_retransmit_sends_a_relayed_frame_again_and_receivers_keep_one():
    # Mesh Profile 4.2.20 Relay Retransmit: 1 + count copies, interval apart; the cache drops copies
    air = chain(3, configs={2: MeshConfig(relay_retransmit_count=2, relay_retransmit_interval_s=0.02,
                                          relay_pace_s=0.0)})  # unpaced: the interval alone
    air.send(1, stop(1, 3, seq=1))
    air.run_until(1.0)
    copies = [s for s in air.log if s.sender == 2]
    assert [round(s.now, 3) for s in copies] == [0.0, 0.02, 0.04] and len({s.tx.data for s in copies}) == 1
    assert len(delivered(air, 3)) == 1 and air.nodes[3].stats.dropped_cached == 2
