"""Replayed segment frames against authenticated mesh nodes (sans-IO, a fake clock): a recorded segment
keeps no silent robot alive, takes no reassembly slot and is not relayed (issue 17, item 6)."""

from __future__ import annotations

from rescuemesh.mesh import FrameDelivered, MeshConfig, MeshNode, NeighbourLost
from rescuemesh.mesh.keys import derive_frame_key, team_key_from_seed
from rescuemesh.mesh.security import FrameSealer

from .frames import data, heartbeat

TEAM = FrameSealer(derive_frame_key(team_key_from_seed(1)))
STEP_S = 0.005


class Air:
    """Nodes by address on one fake clock; `links` who hears whom; `drop(sender, receiver, data)` loses a
    frame (what it lost is kept in `lost`, as an attacker's radio nearer the sender would have it)."""

    def __init__(self, nodes: list[MeshNode], links: set[frozenset[int]] | None = None, drop=None) -> None:
        self.nodes = {n.address: n for n in nodes}
        self.links, self.drop = links, drop
        self.now = 0.0
        self.sent: dict[int, list[bytes]] = {a: [] for a in self.nodes}
        self.lost: list[bytes] = []
        self.events: dict[int, list] = {a: [] for a in self.nodes}

    def run(self, seconds: float, silent: frozenset[int] = frozenset()) -> None:
        end = self.now + seconds
        while self.now < end:
            self.now = round(self.now + STEP_S, 9)
            for node in self.nodes.values():
                timer = node.get_timer()
                if timer is not None and timer <= self.now:
                    node.handle_timer(self.now)
                for tx in node.transmissions(self.now):
                    if node.address in silent:
                        continue
                    self.sent[node.address].append(tx.data)
                    for other in self.nodes.values():
                        if other is node or (self.links is not None
                                             and frozenset((node.address, other.address)) not in self.links):
                            continue
                        if self.drop is not None and self.drop(node.address, other.address, tx.data):
                            self.lost.append(tx.data)
                            continue
                        other.receive(tx.data, self.now)
                while (event := node.next_event()) is not None:
                    self.events[node.address].append(event)


def introduce(air: Air) -> None:
    """Every node sends a Heartbeat (its peers learn its epoch), as robots do at start."""
    for node in air.nodes.values():
        node.send(heartbeat(node.address, 0), air.now)
    air.run(0.1)


def secure(address: int, relay: bool = False) -> MeshNode:
    return MeshNode(address, MeshConfig(relay=relay, relay_pace_s=0.0), TEAM)


def transfers(events: list) -> list[FrameDelivered]:
    """The segmented frames delivered (Heartbeats are delivered too)."""
    return [e for e in events if isinstance(e, FrameDelivered) and len(e.data) > 20]


def segments(frames: list[bytes]) -> list[bytes]:
    return [f for f in frames if f[0] & 0x10]


def test_a_replayed_segment_does_not_keep_a_silent_robot_alive():
    # this used to keep robot 1 reachable at 63 s: one of its recorded segments, replayed once a
    # second, refreshed its neighbour entry (only the 0.75 s network cache stood in the way)
    a, b = secure(1), secure(2)
    air = Air([a, b])
    introduce(air)
    a.send(data(1, 2, seq=1, size=80), air.now)  # five segments
    air.run(1.0)
    assert len(transfers(air.events[2])) == 1
    recorded = segments(air.sent[1])
    assert recorded
    for k in range(12):  # robot 1 is gone; an attacker replays one of its segments every second
        b.receive(recorded[k % len(recorded)], air.now)
        air.run(1.0, silent=frozenset({1}))
    assert not b.is_reachable(1, air.now)
    assert any(isinstance(e, NeighbourLost) and e.address == 1 for e in air.events[2])
    assert b.stats.dropped_replay >= 12


def test_replayed_segments_of_old_transfers_take_no_reassembly_slot():
    # this used to fill robot 1's two reassembly slots on robot 2 with one replayed segment from each
    # of two old transfers, so that robot 1's next genuine transfer was refused
    first_round_of = {1: 2, 2: 2}  # segment 2 of each transfer is lost in its first round

    def drop(sender: int, receiver: int, frame: bytes) -> bool:
        if sender != 1 or not frame[0] & 0x10:
            return False
        seq = int.from_bytes(frame[4:6], "big")
        segment, round_ = int.from_bytes(frame[6:9], "big") >> 12, frame[1] >> 6
        return round_ == 0 and first_round_of.get(seq) == segment

    a, b = secure(1), secure(2)
    air = Air([a, b], drop=drop)
    introduce(air)
    for seq in (1, 2):
        a.send(data(1, 2, seq=seq, size=80), air.now)
        air.run(1.5)
    assert len(transfers(air.events[2])) == 2
    assert len(air.lost) == 2  # round-0 copies robot 2 never accepted: an attacker's best replay
    air.run(11.0)  # the receiver's memory of the completed transfers has lapsed
    for frame in air.lost + segments(air.sent[1]):
        b.receive(frame, air.now)
    rejected = b.stats.reassemblies_rejected
    a.send(data(1, 2, seq=4, size=80), air.now)
    air.run(1.5)
    delivered = transfers(air.events[2])
    assert len(delivered) == 3 and delivered[-1].data == data(1, 2, seq=4, size=80)
    assert b.stats.reassemblies_rejected - rejected == 0


def test_a_replayed_segment_is_not_relayed():
    a, relay, b = secure(1), secure(3, relay=True), secure(2)
    air = Air([a, relay, b], links={frozenset((1, 3)), frozenset((3, 2))})
    introduce(air)
    a.send(data(1, 2, seq=1, size=80), air.now)
    air.run(1.5)
    relayed = relay.stats.relayed
    for frame in segments(air.sent[1]):  # after the network cache has forgotten them
        relay.receive(frame, air.now)
    air.run(0.5)
    assert relay.stats.relayed == relayed
