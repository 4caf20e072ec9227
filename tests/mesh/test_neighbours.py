"""Neighbours and liveness: hops from heartbeats, lost after 3 missed heartbeats, found again."""

from __future__ import annotations

import pytest

from rescuemesh.mesh import MeshConfig, MeshNode, NeighbourFound, NeighbourLost
from rescuemesh.mesh.neighbours import NeighbourTable

from .chain import RSSI_DBM, chain
from .frames import heartbeat, stop


def drain(node):
    """The liveness events of `node` (the heartbeats' FrameDelivered events left out)."""
    events = []
    while (event := node.next_event()) is not None:
        if type(event) in (NeighbourFound, NeighbourLost):
            events.append(event)
    return events


def beat(node, src, seq, now, ttl=7, init_ttl=None):
    node.receive(heartbeat(src, seq, ttl, init_ttl), now, rssi_dbm=RSSI_DBM)
    node.transmissions(now)  # the relayed copy: not what these tests are about


def lone(**config):
    """Node 1 alone: heartbeats are injected, nothing else happens."""
    return MeshNode(1, MeshConfig(**config))


def test_hops_are_learned_from_the_heartbeat_init_ttl():
    air = chain(5)
    air.send(1, heartbeat(1, seq=1, ttl=5))  # init_ttl 5, not the team's default 7
    assert [air.nodes[a].hops_to(1) for a in range(2, 6)] == [1, 2, 3, 4]
    air.send(1, stop(1, 5, seq=2, ttl=5))  # later frames use the learned init_ttl
    assert air.of_type(5, NeighbourFound)[0].hops == 4


def test_without_a_heartbeat_hops_count_from_the_configured_initial_ttl():
    node = MeshNode(1, MeshConfig(initial_ttl=5))
    node.receive(stop(2, 1, seq=1, ttl=3), 0.0)
    assert node.hops_to(2) == 3  # 5 - 3 + 1


def test_rssi_is_kept_for_direct_receptions_only():
    air = chain(3)
    air.send(1, heartbeat(1, seq=1))
    [(info2)] = [n for n in air.nodes[2].neighbours() if n.address == 1]
    [(info3)] = [n for n in air.nodes[3].neighbours() if n.address == 1]
    assert (info2.hops, info2.rssi_dbm) == (1, RSSI_DBM)
    assert (info3.hops, info3.rssi_dbm) == (2, None)


def test_a_relayed_frame_not_for_us_counts_as_hearing_its_source():
    air = chain(3)
    air.send(3, stop(3, 1, seq=1))  # passes node 2 on its way to node 1
    assert air.nodes[2].is_reachable(3, air.now)
    assert air.nodes[1].hops_to(3) == 2


def test_a_peer_is_lost_after_three_missed_heartbeats_exactly_at_the_documented_time():
    node = lone()
    for i in range(6):
        beat(node, 2, seq=i, now=float(i))
    assert [type(e) for e in drain(node)] == [NeighbourFound]  # found once, not per heartbeat
    # last heard at 5.0 s; heartbeats due at 6, 7 and 8 s missed; lost at 5 + 3.5 s
    assert node.get_timer() == 8.5
    node.handle_timer(8.499)
    assert drain(node) == [] and node.is_reachable(2, 8.499)
    node.handle_timer(8.5)
    assert drain(node) == [NeighbourLost(2, 5.0, 8.5)]
    assert not node.is_reachable(2, 8.5)
    node.handle_timer(9.5)
    assert drain(node) == []  # lost once
    assert [n.lost for n in node.neighbours()] == [True]
    assert node.hops_to(2) == 1  # the last known path is kept while lost


def test_is_reachable_applies_the_rule_without_waiting_for_the_timer():
    node = lone()
    beat(node, 2, seq=1, now=0.0)
    assert node.is_reachable(2, 3.4999)
    assert not node.is_reachable(2, 3.5)
    assert not node.is_reachable(3, 0.0)  # never heard


def test_a_lost_peer_is_found_again_once():
    node = lone()
    beat(node, 2, seq=1, now=0.0)
    node.handle_timer(3.5)
    beat(node, 2, seq=2, now=10.0, ttl=6, init_ttl=7)  # back, now through a relay
    beat(node, 2, seq=3, now=11.0, ttl=6, init_ttl=7)
    assert drain(node) == [NeighbourFound(2, 1, 0.0), NeighbourLost(2, 0.0, 3.5), NeighbourFound(2, 2, 10.0)]
    assert node.get_timer() == 11.0 + 3.5


def test_a_peer_unheard_for_the_expiry_time_is_forgotten_and_found_anew():
    node = lone(neighbour_expiry_s=20.0)
    beat(node, 2, seq=1, now=0.0)
    node.handle_timer(3.5)
    assert node.get_timer() == 20.0
    node.handle_timer(20.0)
    assert node.neighbours() == [] and node.hops_to(2) is None
    assert node.get_timer() is None
    beat(node, 2, seq=2, now=30.0)
    assert [type(e) for e in drain(node)] == [NeighbourFound, NeighbourLost, NeighbourFound]


def test_lost_after_missed_and_heartbeat_period_scale_the_loss_time():
    node = lone(heartbeat_period_s=2.0, lost_after_missed=4)
    beat(node, 2, seq=1, now=1.0)
    assert node.get_timer() == 1.0 + 4.5 * 2.0


@pytest.mark.parametrize("ttl, init_ttl, hops", [(7, 7, 1), (3, 7, 5), (0, 15, 16), (9, 7, 1)])
def test_hops_for(ttl, init_ttl, hops):
    # at least 1 even when the TTL is above the init_ttl assumed (a source with another config)
    table = NeighbourTable(MeshConfig())
    assert table.hops_for(2, ttl, init_ttl) == hops


def test_a_heartbeat_with_an_impossible_init_ttl_teaches_nothing():
    node = lone()
    frame = bytearray(heartbeat(2, seq=1, ttl=5))
    frame[7] = 200  # init_ttl beyond 15: a broken sender (the CRC is fixed below)
    import zlib

    frame[-4:] = zlib.crc32(bytes(frame[:-4])).to_bytes(4, "big")
    node.receive(bytes(frame), 0.0)
    assert node.neighbours()[0].init_ttl is None and node.hops_to(2) == 3  # from initial_ttl 7


def test_the_cached_next_deadline_always_equals_a_full_scan():
    # the node asks for its timer after every frame heard; the table now keeps the minimum instead
    # of rescanning every entry, and must never keep a stale one
    import random

    from rescuemesh.mesh import MeshConfig
    from rescuemesh.mesh.neighbours import NeighbourTable

    config = MeshConfig()
    rng = random.Random(3)
    for trial in range(30):
        table, now = NeighbourTable(config), 0.0
        for _ in range(300):
            now += rng.choice([0.001, 0.05, 0.3, 1.0, 4.0, 30.0])
            action = rng.random()
            if action < 0.7:
                table.heard(rng.randint(1, 12), 7, now, -60.0, 7 if rng.random() < 0.3 else None)
            else:
                table.expire(now)
            entries = table._entries.values()
            scan = min((e.last_heard_s + (config.neighbour_expiry_s if e.lost else config.lost_after_seconds)
                        for e in entries), default=None)
            assert table.next_deadline() == scan
