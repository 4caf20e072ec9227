"""Taming the flood: counter-based relay suppression (Ni et al., MobiCom 1999), relay pacing and
stale relays, and the TTL of unicast frames from the neighbour table (docs/mesh.md section 12)."""

from __future__ import annotations

import math

import pytest

from rescuemesh.mesh import FrameDelivered, MeshConfig, MeshNode
from rescuemesh.mesh.frames import read_on_air, with_ttl
from rescuemesh.protocol import BROADCAST, MessageType

from .chain import RSSI_DBM, mesh
from .frames import heartbeat, pose_update, stop

#: Three copies 20 ms apart per relayed frame, as the simulated team has them.
#: Unpaced and never stale, so a test may ask for everything at once.
TEAM = dict(relay_retransmit_count=2, relay_retransmit_interval_s=0.02, relay_pace_s=0.0,
            relay_max_wait_s=math.inf)


def relay_node(**overrides) -> MeshNode:
    return MeshNode(2, MeshConfig(**{**TEAM, **overrides}))


def ttls(transmissions) -> list[int]:
    return [t.ttl for t in transmissions]


# --- counter-based suppression -------------------------------------------------------------------

@pytest.mark.parametrize("k", [1, 2, 3])
def test_a_relay_that_hears_k_copies_from_other_relays_cancels_its_pending_copies(k):
    # this used to send all three copies whatever it heard: O(N^2) airtime in a dense team
    node = relay_node(relay_suppress_after=k)
    frame = stop(1, 3, seq=1)
    node.receive(frame, 0.0, relay_delay_s=0.01)
    for i in range(k - 1):
        node.receive(with_ttl(frame, 6), 0.002 + 0.001 * i)  # another relay's copy
    assert node.stats.relays_suppressed == 0
    node.receive(with_ttl(frame, 6), 0.009)
    assert node.get_timer() == 3.5  # only node 1's liveness deadline is left: no copy waits
    assert node.transmissions(1.0) == []
    assert (node.stats.relays_suppressed, node.stats.relay_copies_suppressed) == (1, 3)
    assert node.stats.dropped_cached == k


def test_with_fewer_copies_heard_than_the_threshold_every_copy_goes():
    node = relay_node(relay_suppress_after=2)
    frame = stop(1, 3, seq=1)
    node.receive(frame, 0.0, relay_delay_s=0.01)
    node.receive(with_ttl(frame, 6), 0.005)
    assert ttls(node.transmissions(1.0)) == [6, 6, 6] and node.stats.relays_suppressed == 0


def test_copies_already_handed_out_go_the_rest_are_cancelled():
    node = relay_node(relay_suppress_after=1)
    frame = stop(1, 3, seq=1)
    node.receive(frame, 0.0, relay_delay_s=0.0)
    assert len(node.transmissions(0.0)) == 1  # the first copy is the transport's now
    node.receive(with_ttl(frame, 6), 0.01)
    assert node.transmissions(1.0) == [] and node.stats.relay_copies_suppressed == 2


def test_the_relay_retransmissions_of_the_node_we_heard_do_not_count():
    # a chain: node 2 hears node 1's three copies (TTL 7, as first heard); suppressing on them
    # would silence every relay of a chain whose delay is longer than the retransmit interval
    node = relay_node(relay_suppress_after=1)
    frame = stop(1, 3, seq=1, ttl=7)
    node.receive(frame, 0.0, relay_delay_s=0.03)
    node.receive(frame, 0.02)
    assert ttls(node.transmissions(1.0)) == [6, 6, 6] and node.stats.relays_suppressed == 0


def test_a_copy_from_further_along_counts_as_a_passive_ack():
    node = relay_node(relay_suppress_after=1)
    frame = stop(1, 5, seq=1)
    node.receive(frame, 0.0, relay_delay_s=0.0)
    assert len(node.transmissions(0.0)) == 1
    node.receive(with_ttl(frame, 5), 0.01)  # node 3 relayed our copy on
    assert node.transmissions(1.0) == []


@pytest.mark.parametrize("off", [0, None])
def test_suppression_off_sends_every_copy(off):
    node = relay_node(relay_suppress_after=off)
    frame = stop(1, 3, seq=1)
    node.receive(frame, 0.0, relay_delay_s=0.01)
    for t in (0.002, 0.003, 0.004):
        node.receive(with_ttl(frame, 6), t)
    assert ttls(node.transmissions(1.0)) == [6, 6, 6]


def test_a_frame_whose_copies_still_wait_is_a_duplicate_even_after_its_cache_entry_expired():
    node = relay_node(relay_suppress_after=3, relay_pace_s=1.0, cache_lifetime_s=0.1)
    frame = stop(1, 3, seq=1)
    node.receive(stop(1, 4, seq=9), 0.0)  # another relay holds the pace
    node.transmissions(0.0)
    node.receive(frame, 0.0)
    node.receive(with_ttl(frame, 6), 0.5)  # past the cache lifetime, the copies still wait
    assert node.stats.relayed == 2 and node.stats.dropped_cached == 1


def test_in_a_dense_cluster_one_relay_covers_what_five_would_have():
    # six nodes that all hear each other; node 1 sends to node 6
    addresses = range(1, 7)
    links = [(a, b) for a in addresses for b in addresses if a < b]
    delays = {2: 0.001, 3: 0.004, 4: 0.006, 5: 0.008}
    air = mesh(addresses, links, MeshConfig(**TEAM, relay_suppress_after=1),
               relay_delay=lambda address, data: delays.get(address, 0.0))
    air.send(1, stop(1, 6, seq=1, ttl=3))
    air.run_until(1.0)
    relayed = [s for s in air.log if s.tx.relayed]
    assert {s.sender for s in relayed} == {2} and len(relayed) == 3
    assert len(air.of_type(6, FrameDelivered)) == 1


# --- pacing and stale relays -------------------------------------------------------------------

def test_relays_leave_at_most_one_per_pace_and_our_own_frames_do_not_wait():
    node = relay_node(relay_suppress_after=0, relay_retransmit_count=0, relay_pace_s=0.03)
    for seq in range(3):
        node.receive(stop(1, 3, seq=seq), 0.0)
    assert len(node.transmissions(0.0)) == 1 and node.get_timer() == pytest.approx(0.03)
    node.send(stop(2, 3, seq=7), 0.01)
    assert [t.relayed for t in node.transmissions(0.01)] == [False]
    assert node.get_timer() == pytest.approx(0.04)  # our frame took a turn
    assert len(node.transmissions(0.04)) == 1 and len(node.transmissions(0.07)) == 1


def test_a_relay_that_waited_longer_than_relay_max_wait_is_dropped():
    node = relay_node(relay_suppress_after=0, relay_retransmit_count=0, relay_pace_s=0.2,
                      relay_max_wait_s=0.1)
    node.receive(stop(1, 3, seq=1), 0.0)
    node.receive(stop(1, 3, seq=2), 0.0)
    assert len(node.transmissions(0.0)) == 1
    assert node.transmissions(0.2) == [] and node.stats.relays_expired == 1


# --- TTL of unicast frames from the neighbour table ----------------------------------------------

def sender(**overrides) -> MeshNode:
    """A node in a dense team (no sparse-team slack) unless `sparse_neighbours` is given."""
    return MeshNode(1, MeshConfig(**{"sparse_neighbours": 0, **overrides}))


def learn(node: MeshNode, src: int, hops: int, now: float = 0.0) -> None:
    node.receive(heartbeat(src, seq=100 + src, ttl=8 - hops, init_ttl=7), now, rssi_dbm=RSSI_DBM)
    assert node.hops_to(src) == hops


def sent_ttl(node: MeshNode, frame: bytes, now: float) -> int:
    node.send(frame, now)
    [tx] = [t for t in node.transmissions(now) if not t.relayed]
    assert tx.data[0] & 0x0F == tx.ttl  # the bytes carry it (CRC recomputed: decodable)
    return tx.ttl


def test_a_unicast_to_a_one_hop_neighbour_goes_out_with_ttl_1():
    # this used to flood every frame with TTL 7, across the whole team; TTL 1 is not relayed
    node = sender()
    learn(node, 2, hops=1)
    assert sent_ttl(node, stop(1, 2, seq=1), 0.1) == 1
    assert node.stats.sent_short_ttl == 1


def test_a_unicast_two_hops_away_goes_out_with_ttl_2():
    node = sender()
    learn(node, 3, hops=2)
    assert sent_ttl(node, stop(1, 3, seq=1), 0.1) == 2


def test_a_node_with_few_neighbours_gives_its_frames_a_hop_of_slack():
    # a team of four at 30 % loss got 93 % of its commands through without it (99.95 % with)
    node = sender(sparse_neighbours=6)
    learn(node, 2, hops=1)
    assert sent_ttl(node, stop(1, 2, seq=1), 0.1) == 2
    for src in range(3, 9):  # seven neighbours: a dense team
        learn(node, src, hops=1, now=0.2)
    assert sent_ttl(node, stop(1, 2, seq=2), 0.3) == 1


def test_slack_adds_hops():
    node = sender(unicast_ttl_slack=1)
    learn(node, 2, hops=1)
    assert sent_ttl(node, stop(1, 2, seq=1), 0.1) == 2


def test_an_unknown_destination_gets_ttl_7():
    assert sent_ttl(sender(), stop(1, 9, seq=1), 0.0) == 7


def test_a_lost_destination_gets_ttl_7():
    node = sender()
    learn(node, 2, hops=1)
    assert sent_ttl(node, stop(1, 2, seq=1), 10.0) == 7  # lost 3.5 s after last heard


def test_each_resend_may_travel_one_hop_further():
    # the endpoint resends with attempt bits > 0: the short path may be the one that failed. Full
    # TTL on every resend flooded the team of 30 with a third of its airtime
    node = sender()
    learn(node, 2, hops=1)
    assert [sent_ttl(node, stop(1, 2, seq=s, attempt=a), 0.1) for s, a in ((1, 1), (2, 2), (3, 3))] == [2, 3, 4]


def test_pose_update_resends_keep_the_first_sends_ttl():
    # the next PoseUpdate comes within 0.5 s: a 30-robot convoy's PoseUpdate resends flooding 2-3
    # hops were 25,000 of its 85,000 transmissions, and their collisions lost more than they saved
    node = sender()
    learn(node, 2, hops=1)
    assert [sent_ttl(node, pose_update(1, 2, seq=s, attempt=a), 0.1) for s, a in ((1, 0), (2, 1), (3, 3))] == [1, 1, 1]
    learn(node, 3, hops=2)
    assert sent_ttl(node, pose_update(1, 3, seq=4, attempt=2), 0.1) == 2


def test_broadcasts_keep_their_ttl():
    node = sender()
    learn(node, 2, hops=1)
    assert sent_ttl(node, heartbeat(1, seq=1), 0.1) == 7
    assert BROADCAST not in [n.address for n in node.neighbours()]


def test_ttl_from_hops_off_keeps_the_endpoints_ttl():
    node = sender(unicast_ttl_from_hops=False)
    learn(node, 2, hops=1)
    assert sent_ttl(node, stop(1, 2, seq=1), 0.1) == 7


def test_a_short_ttl_frame_counts_the_hops_the_heartbeat_measured():
    # TTL 2 heard directly would read as 7 - 2 + 1 = 6 hops without the heartbeat's measure
    node = MeshNode(2, MeshConfig())
    learn(node, 1, hops=1)
    node.receive(stop(1, 2, seq=5, ttl=2), 0.2, rssi_dbm=RSSI_DBM)
    events = []
    while (e := node.next_event()) is not None:
        events.append(e)
    [delivered] = [e for e in events if type(e) is FrameDelivered and e.data[1] & 0x3F == 6]  # the Stop
    assert delivered.hops == 1 and node.hops_to(1) == 1


def test_a_destination_heard_only_through_other_frames_gets_ttl_7():
    # this used to make robot_1 read a TTL 2 Confirm as 6 hops: robot_2 knew robot_1 from its
    # command alone, while robot_1 had not heard robot_2's heartbeat (their first ones collided)
    node = sender()
    node.receive(stop(2, 1, seq=1), 0.0, rssi_dbm=RSSI_DBM)
    assert node.hops_to(2) == 1
    assert sent_ttl(node, stop(1, 2, seq=1), 0.1) == 7


def test_a_heartbeat_is_relayed_once_a_command_with_its_retransmissions():
    # heartbeats used to go out three times from every relay: a third of a 30-robot team's airtime
    node = relay_node(relay_suppress_after=None)
    node.receive(heartbeat(1, seq=1), 0.0, relay_delay_s=0.0)
    node.receive(stop(1, 3, seq=2), 0.0, relay_delay_s=0.0)
    sent = node.transmissions(1.0)
    assert sorted(MessageType(t.msg_type).name for t in sent) == ["HEARTBEAT", "STOP", "STOP", "STOP"]


def test_heartbeats_go_out_with_the_heartbeat_ttl_and_announce_it():
    from rescuemesh.protocol import Endpoint, EndpointConfig

    endpoint = Endpoint(1, EndpointConfig(initial_ttl=7, heartbeat_ttl=3))
    endpoint.send_heartbeat(0.0)
    [frame] = endpoint.frames_to_send(0.0)
    assert read_on_air(frame).ttl == 3
    node = MeshNode(2, MeshConfig())
    node.receive(frame, 0.0, rssi_dbm=RSSI_DBM)
    assert node.hops_to(1) == 1  # hops counted from the announced init_ttl (3 - 3 + 1)


def test_a_heartbeat_waits_longer_to_be_relayed_so_that_others_relaying_it_first_cancel_it():
    # heartbeats were relayed 0-10 ms after arrival like commands: six or seven relays per heartbeat
    # in a team of 30, before any could hear another's copy
    node = relay_node(relay_suppress_after=1, heartbeat_relay_delay_scale=5.0)
    node.receive(heartbeat(1, seq=1, ttl=3), 0.0, relay_delay_s=0.008)
    node.receive(stop(1, 3, seq=2), 0.0, relay_delay_s=0.008)
    assert [MessageType(t.msg_type).name for t in node.transmissions(0.0081)] == ["STOP"]
    node.receive(heartbeat(1, seq=1, ttl=2, init_ttl=3), 0.02)  # another relay's copy, heard meanwhile
    assert [MessageType(t.msg_type).name for t in node.transmissions(1.0)] == ["STOP", "STOP"]
    assert node.stats.relays_suppressed == 1


def test_a_frame_on_its_last_hop_to_another_robot_is_dropped_unopened():
    # every robot used to open, cache and log each of the thousand frames a second a team of 30 hears
    node = relay_node()
    node.receive(stop(1, 3, seq=1, ttl=1), 0.0, rssi_dbm=RSSI_DBM)
    assert node.stats.dropped_passing == 1 and node.stats.accepted == 0 and node.hops_to(1) is None
    node.receive(stop(1, 2, seq=2, ttl=1), 0.0, rssi_dbm=RSSI_DBM)  # for us: opened and delivered
    assert node.stats.accepted == 1 and node.stats.dropped_passing == 1


def test_a_last_hop_copy_still_cancels_our_waiting_copies_of_it():
    node = relay_node(relay_suppress_after=1)
    frame = stop(1, 3, seq=1, ttl=3)
    node.receive(frame, 0.0, relay_delay_s=0.01)  # our copies (TTL 2) wait
    node.receive(with_ttl(frame, 1), 0.005)  # a relay further along sent its last-hop copy
    assert node.stats.dropped_passing == 0 and node.stats.relays_suppressed == 1
    assert node.transmissions(1.0) == []
