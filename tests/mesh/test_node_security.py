"""Authenticated frames through real network stacks (endpoint + mesh node): every attack the issue
lists, as a regression test. Each used to succeed with CRC frames; a fake clock, an in-memory air."""

from __future__ import annotations

import pytest

from rescuemesh.mesh import MeshConfig, MeshNode, NetworkStack, PeerRestarted
from rescuemesh.mesh.keys import derive_frame_key, team_key_from_seed
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import (
    CommandReceived, ConfirmReceived, DeliveryFailed, Endpoint, EndpointConfig, Follow, HeartbeatReceived,
    MessageType, Pose, ReliabilityConfig, ResultCode, Stop, encode_frame)
from rescuemesh.protocol.codec import PROTOCOL_VERSION, FrameFlags, Header
from rescuemesh.protocol.messages import Confirm

TEAM = FrameSealer(derive_frame_key(team_key_from_seed(1)))
INTRUDER = FrameSealer(derive_frame_key(team_key_from_seed(2)))  # a key, but not the team's
SECURE = ReliabilityConfig(duplicate_window_s=float("inf"), duplicate_cache_size=1024)


def stack(address: int, epoch: int = 0, relay: bool = True, announce: bool = False) -> NetworkStack:
    endpoint = Endpoint(address, EndpointConfig(reliability=SECURE, initial_epoch=epoch,
                                                announce_epoch_on_resend=announce))
    # no relay pacing: this harness pumps at one instant (pacing: test_suppression.py)
    return NetworkStack(endpoint, MeshNode(address, MeshConfig(relay=relay, relay_pace_s=0.0), TEAM))


class Air:
    """Who hears whom (`links`), what is lost (`lose(sender, receiver, data)` True), a fake clock, and
    a log of every frame put on the air."""

    def __init__(self, stacks: list[NetworkStack], links: set[frozenset[int]] | None = None,
                 lose=None) -> None:
        self.stacks = {s.address: s for s in stacks}
        self.links = links
        self.lose = lose
        self.now = 0.0
        self.heard: dict[int, list[bytes]] = {a: [] for a in self.stacks}  # what each could capture

    def hears(self, a: int, b: int) -> bool:
        return self.links is None or frozenset((a, b)) in self.links

    def pump(self, until: float | None = None) -> None:
        until = self.now if until is None else until
        for _ in range(10_000):
            moved = False
            for s in self.stacks.values():
                timer = s.get_timer()
                if timer is not None and timer <= until:
                    self.now = max(self.now, timer)
                    s.handle_timer(self.now)
                for tx in s.transmissions(self.now):
                    moved = True
                    self.inject(tx.data, s.address)
            if not moved and not any((t := s.get_timer()) is not None and t <= until for s in self.stacks.values()):
                break
        self.now = max(self.now, until)

    def inject(self, data: bytes, sender: int | None = None) -> None:
        for address, s in self.stacks.items():
            if address != sender and (sender is None or self.hears(sender, address)) \
                    and not (self.lose is not None and self.lose(sender, address, data)):
                self.heard[address].append(data)
                s.receive(data, self.now)


def events(s: NetworkStack) -> list:
    out = []
    while (e := s.endpoint.next_event()) is not None:
        out.append(e)
    return out


def introduce(air: Air) -> None:
    """Everyone sends a Heartbeat: peers learn each other's epoch (what robots do at start)."""
    for s in air.stacks.values():
        s.endpoint.send_heartbeat(air.now)
    air.pump()
    for s in air.stacks.values():
        events(s)


def forged(src: int, dst: int, message, seq: int = 9, sealer: FrameSealer | None = INTRUDER) -> bytes:
    frame = encode_frame(Header(PROTOCOL_VERSION, FrameFlags.NONE, 7, 0, message.TYPE, src, dst, seq), message)
    return frame if sealer is None else sealer.seal(frame, 0)


def test_a_command_between_team_members_is_sealed_opened_and_delivered_once():
    a, b = stack(1), stack(2)
    air = Air([a, b])
    introduce(air)
    seq = a.endpoint.send_command(2, Follow(Pose(1, 2, 0, 0)), air.now)
    air.pump()
    (received,) = events(b)
    assert isinstance(received, CommandReceived) and received.seq == seq
    assert all(data[0] & 0x20 for data in air.heard[2])  # every frame on the air is authenticated


@pytest.mark.parametrize("sealer", [None, INTRUDER], ids=["no key (CRC frame)", "wrong key"])
def test_a_forged_stop_from_robot_1_is_dropped_and_goes_no_further_than_the_first_relay(sealer):
    # this used to halt robot_2: `43 06 01 02 ...` with a good CRC was obeyed from any radio
    a, relay, b = stack(1), stack(3), stack(2)
    air = Air([a, relay, b], links={frozenset((1, 3)), frozenset((3, 2))})
    introduce(air)
    air.stacks[3].receive(forged(1, 2, Stop(), sealer=sealer), air.now)
    air.pump(air.now + 0.5)
    assert events(b) == [] and not any(d == forged(1, 2, Stop(), sealer=sealer) for d in air.heard[2])
    stats = relay.node.stats
    assert stats.dropped_forged + stats.dropped_unauthenticated == 1 and stats.relayed == stats.relayed


def test_a_flipped_bit_anywhere_is_dropped():
    a, b = stack(1), stack(2)
    air = Air([a, b])
    introduce(air)
    a.endpoint.send_command(2, Stop(), air.now)
    (tx,) = a.transmissions(air.now)
    for bit in range(len(tx.data) * 8):
        flipped = bytearray(tx.data)
        flipped[bit // 8] ^= 1 << (bit % 8)
        b.receive(bytes(flipped), air.now)
    assert events(b) == []
    b.receive(tx.data, air.now)
    assert [type(e) for e in events(b)] == [CommandReceived]


@pytest.mark.parametrize("delay_s", [0.5, 10.01, 15.0, 25.0, 60.0, 3600.0])
def test_a_captured_stop_replayed_later_is_never_executed_again(delay_s):
    # this used to execute a Stop replayed 10.01 s, 25 s or an hour later once more
    a, b = stack(1), stack(2)
    air = Air([a, b])
    introduce(air)
    a.endpoint.send_command(2, Stop(), air.now)
    air.pump()
    captured = list(air.heard[2])
    assert [type(e) for e in events(b)] == [CommandReceived]
    t = air.now + delay_s
    while air.now < t:  # the team goes on: heartbeats every second
        air.pump(min(t, air.now + 1.0))
        a.endpoint.send_heartbeat(air.now)
    air.pump()
    for data in captured:
        air.inject(data)
    air.pump()
    assert [e for e in events(b) if isinstance(e, CommandReceived)] == []
    s = b.node.stats  # (robot_2 also captured its own Heartbeat, relayed back: dropped as its own)
    assert s.dropped_replay + s.dropped_cached + s.dropped_own >= len(captured)
    assert s.dropped_replay >= 1 or delay_s < MeshConfig().cache_lifetime_s  # the cache caught it first


def stop_received_once(a: NetworkStack, b: NetworkStack, air: Air) -> int:
    """robot_1 sends robot_2 a Stop that arrives once; returns its seq."""
    introduce(air)
    seq = a.endpoint.send_command(2, Stop(), air.now)
    (first,) = a.transmissions(air.now)
    b.receive(first.data, air.now)
    assert [type(e) for e in events(b)] == [CommandReceived]
    return seq


def test_a_late_genuine_resend_is_answered_from_the_cache_not_executed_twice():
    # this used to execute twice a resend that arrived 10.2 s after the original
    a, b = stack(1), stack(2)
    air = Air([a, b])
    seq = stop_received_once(a, b, air)
    b.endpoint.confirm(1, seq, MessageType.STOP, ResultCode.DONE, air.now)
    b.transmissions(air.now)  # that Confirm is lost
    a.handle_timer(air.now + 0.15)
    (resend,) = a.transmissions(air.now + 0.15)
    air.now += 10.2
    b.receive(resend.data, air.now)  # arrives 10.2 s late
    assert events(b) == [] and b.endpoint.stats.duplicates == 1
    (answer,) = b.transmissions(air.now)  # the cached DONE again, under a fresh number
    a.receive(answer.data, air.now)
    assert [(e.result, e.solicited) for e in events(a)] == [(ResultCode.DONE, True)]


def test_a_flood_of_forged_frames_cannot_evict_state_and_cause_a_double_execution():
    # this used to work: 256 spoofed frames from one source evicted the duplicate cache
    a, b = stack(1), stack(2)
    air = Air([a, b])
    seq = stop_received_once(a, b, air)
    for k in range(1000):
        b.receive(forged(1, 2, Follow(Pose(k % 50, 1, 0, 0)), seq=(seq + 1 + k) & 0xFFFF), air.now)
    a.handle_timer(air.now + 0.15)
    (resend,) = a.transmissions(air.now + 0.15)
    b.receive(resend.data, air.now + 0.15)
    assert events(b) == [] and b.node.stats.dropped_forged == 1000


def test_a_spoofed_confirm_never_cancels_a_resend_nor_reports_success():
    # this used to stop the retries of a lost Stop: a Confirm "from robot_2" from anyone counted
    a, b = stack(1), stack(2)
    air = Air([a, b])
    introduce(air)
    seq = a.endpoint.send_command(2, Stop(), air.now)
    a.transmissions(air.now)  # the Stop is lost
    for sealer in (None, INTRUDER):
        a.receive(forged(2, 1, Confirm(seq, MessageType.STOP, ResultCode.DONE), seq=77, sealer=sealer), air.now)
    assert events(a) == [] and a.endpoint.get_timer() is not None
    air.pump(air.now + 1.0)
    assert a.endpoint.stats.retries >= 1  # the forged Confirms did not stop the resends
    assert [type(e) for e in events(b) if not isinstance(e, HeartbeatReceived)] == [CommandReceived]
    assert not any(isinstance(e, ConfirmReceived) for e in events(a))  # robot_2 has not answered yet


def test_a_rebooted_robot_starts_a_new_epoch_and_its_new_commands_are_accepted():
    # this used to drop a rebooted robot's first command (seq 0 again) and answer an old DONE
    a, b = stack(1), stack(2)
    air = Air([a, b])
    introduce(air)
    a.endpoint.send_command(2, Stop(), air.now)
    air.pump()
    old_frames = list(air.heard[2])
    events(b)
    rebooted = stack(1, epoch=1)  # the boot counter, persisted, went up
    air.stacks[1] = rebooted
    rebooted.endpoint.send_heartbeat(air.now)
    rebooted.endpoint.send_command(2, Stop(), air.now)  # seq 1 again, the same message
    air.pump()
    assert [type(e) for e in events(b) if not isinstance(e, HeartbeatReceived)] == [CommandReceived]
    assert any(isinstance(e, PeerRestarted) and e.epoch == 1 for e in iter(b.next_event, None))
    for data in old_frames:  # what was captured before the reboot
        b.receive(data, air.now + 1.0)
    assert events(b) == [] and b.node.stats.dropped_replay >= 1


def test_a_relay_reseals_with_a_lower_ttl_and_the_far_robot_opens_it():
    a, relay, b = stack(1), stack(3), stack(2)
    air = Air([a, relay, b], links={frozenset((1, 3)), frozenset((3, 2))})
    introduce(air)
    air.pump(air.now + 1.0)
    for s in (a, relay, b):
        s.endpoint.send_heartbeat(air.now)  # heartbeats relayed: robot 1 and 2 learn each other
    air.pump(air.now + 0.5)
    events(b)
    a.endpoint.send_command(2, Stop(), air.now)
    air.pump(air.now + 0.5)
    received = [e for e in events(b) if isinstance(e, CommandReceived)]
    assert received and received[0].hops == 2
    assert not any(isinstance(e, DeliveryFailed) for e in events(a))
