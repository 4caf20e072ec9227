"""The simulated medium: airtime, queues, collisions, capture, half duplex, radio off, per-pair
streams, the timer heap. Fake stacks and channels, so that only the medium is under test."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from rescuemesh.radio import DiscChannel, ble_adv_airtime_s
from rescuemesh.transport.sim_medium import AirTiming, SimMedium

BROADCAST = 0xFF
NO_JITTER = AirTiming(adv_delay_max_s=0.0, relay_delay_max_s=0.0)


@dataclass(frozen=True)
class Tx:
    """The metadata a mesh node attaches to a frame (rescuemesh.mesh.Transmission's fields)."""

    data: bytes
    src: int
    dst: int = BROADCAST
    msg_type: int = 34
    seq: int = 0
    ttl: int = 3
    relayed: bool = False
    segment: int | None = None
    segments: int | None = None


@dataclass
class FakeStack:
    address: int
    outbox: list = field(default_factory=list)
    heard: list = field(default_factory=list)  # (time, data, rssi)
    timer: float | None = None
    fired: list = field(default_factory=list)

    def receive(self, data, now, *, rssi_dbm=None, relay_delay_s=0.0):
        self.heard.append((now, data, rssi_dbm))

    def transmissions(self, now):
        out, self.outbox = self.outbox, []
        return out

    def get_timer(self):
        return self.timer

    def handle_timer(self, now):
        self.fired.append(now)
        self.timer = None


class DistanceChannel(DiscChannel):
    """A disc whose mean received power falls 10 dB per metre (a disc delivers every frame it can at
    its mean power): lets capture be tested."""

    def mean_rx_power_dbm(self, tx_xy, rx_xy):
        d = float(np.hypot(rx_xy[0] - tx_xy[0], rx_xy[1] - tx_xy[1]))
        return -10.0 * d if d <= self.range_m else -np.inf


def medium_with(positions: dict[int, tuple[float, float]], channel=None, **kw):
    medium = SimMedium(channel or DiscChannel(), 7, timing=kw.pop("timing", NO_JITTER), record=True, **kw)
    stacks = {}
    for address, xy in positions.items():
        stacks[address] = FakeStack(address)
        medium.attach(address, stacks[address], lambda xy=xy: xy)
    return medium, stacks


def test_a_frame_arrives_after_its_airtime_and_the_medium_never_reads_it():
    medium, stacks = medium_with({1: (0, 0), 2: (5, 0)})
    stacks[1].outbox.append(Tx(b"not a frame at all", 1, 2))
    medium.pump(0.1)
    ((at, data, _),) = stacks[2].heard
    assert data == b"not a frame at all" and at == pytest.approx(ble_adv_airtime_s(18))
    assert medium.stats.unicast_delivered == 1 and medium.stats.transmissions == 1


def test_beyond_range_nothing_is_heard_and_the_intended_receiver_counts_it_out_of_range():
    medium, stacks = medium_with({1: (0, 0), 2: (50, 0)})
    stacks[1].outbox.append(Tx(b"x" * 20, 1, 2))
    medium.pump(0.1)
    assert stacks[2].heard == [] and medium.stats.receptions_lost["out_of_range"] == 1


def test_one_radio_sends_one_frame_at_a_time_at_least_an_advertising_interval_apart():
    medium, stacks = medium_with({1: (0, 0), 2: (5, 0)})
    stacks[1].outbox += [Tx(bytes([i]) * 20, 1, 2) for i in range(4)]
    medium.pump(1.0)
    starts = [r.start_s for r in medium.records]
    assert len(starts) == 4 and all(b - a >= 0.020 - 1e-12 for a, b in zip(starts, starts[1:]))
    assert [d[0] for _, d, _ in stacks[2].heard] == [0, 1, 2, 3]  # in order


def test_two_frames_overlapping_at_a_receiver_collide_both():
    medium, stacks = medium_with({1: (-3, 0), 2: (3, 0), 3: (0, 0)})
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 3))
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 3))
    medium.pump(0.1)
    assert stacks[3].heard == [] and medium.stats.collisions == 2
    assert all(r.collided for r in medium.records)


def test_a_much_stronger_frame_captures_the_receiver():
    # 1 m away (-10 dB) against 5 m away (-50 dB): 40 dB > 21 dB co-channel rejection
    medium, stacks = medium_with({1: (-1, 0), 2: (5, 0), 3: (0, 0)}, DistanceChannel())
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 3))
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 3))
    medium.pump(0.1)
    assert [d for _, d, _ in stacks[3].heard] == [b"a" * 20] and medium.stats.collisions == 1


def test_frames_that_do_not_overlap_do_not_collide():
    medium, stacks = medium_with({1: (-3, 0), 2: (3, 0), 3: (0, 0)})
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 3))
    medium.pump(0.01)
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 3))
    medium.pump(0.1)
    assert len(stacks[3].heard) == 2 and medium.stats.collisions == 0


def test_a_radio_that_is_sending_hears_nothing():
    medium, stacks = medium_with({1: (0, 0), 2: (3, 0)})
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 2))
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 1))
    medium.pump(0.1)
    assert stacks[1].heard == stacks[2].heard == []
    assert medium.stats.receptions_lost["half_duplex"] == 2


def test_a_radio_switched_off_neither_sends_nor_hears_and_comes_back():
    medium, stacks = medium_with({1: (0, 0), 2: (3, 0)})
    medium.set_radio_enabled(1, False, 0.0)
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 2))
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 1))
    medium.pump(0.1)
    assert stacks[1].heard == stacks[2].heard == []
    assert medium.stats.dropped_radio_off == 1 and medium.stats.receptions_lost["radio_off"] == 1
    medium.set_radio_enabled(1, True, 0.1)
    stacks[2].outbox.append(Tx(b"c" * 20, 2, 1))
    medium.pump(0.2)
    assert [d for _, d, _ in stacks[1].heard] == [b"c" * 20]


def test_stack_timers_fire_at_their_time_from_the_heap():
    medium, stacks = medium_with({1: (0, 0), 2: (3, 0)})
    stacks[1].timer = 0.33
    medium.pump(0.3)
    assert stacks[1].fired == []
    medium.pump(0.4)
    assert stacks[1].fired == [0.33]
    stacks[2].timer = 0.5
    stacks[2].timer = 0.45  # moved earlier before the medium looked: fires once, at 0.45
    medium.pump(1.0)
    assert stacks[2].fired == [0.45]


def test_a_far_away_robot_changes_nothing_for_two_others():
    """Per-pair random streams: what 1 and 2 lose does not depend on who else is attached."""
    def heard(extra: bool):
        positions = {1: (0, 0), 2: (5, 0)} | ({9: (500, 500)} if extra else {})
        medium, stacks = medium_with(positions, extra_loss=0.4, timing=AirTiming())
        for k in range(60):
            stacks[1].outbox.append(Tx(bytes([k]) * 20, 1, 2, seq=k))
            if extra:
                stacks[9].outbox.append(Tx(b"z" * 20, 9, BROADCAST, seq=k))
            medium.pump(k * 0.05)
        medium.pump(10.0)
        return [(round(t, 9), d) for t, d, _ in stacks[2].heard]
    alone, crowded = heard(False), heard(True)
    assert 15 < len(alone) < 50 and alone == crowded


def test_same_seed_same_deliveries_and_another_seed_differs():
    def run(seed):
        medium = SimMedium(DiscChannel(), seed, extra_loss=0.5)
        a, b = FakeStack(1), FakeStack(2)
        medium.attach(1, a, lambda: (0, 0))
        medium.attach(2, b, lambda: (3, 0))
        for k in range(40):
            a.outbox.append(Tx(bytes([k]) * 20, 1, 2))
            medium.pump(k * 0.05)
        medium.pump(5.0)
        return [d[0] for _, d, _ in b.heard]
    assert run(1) == run(1) != run(2)


@pytest.mark.parametrize("kwargs", [dict(extra_loss=1.0), dict(extra_loss=-0.1)])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(ValueError):
        SimMedium(DiscChannel(), 0, **kwargs)


def test_attaching_an_address_twice_is_refused():
    medium, _ = medium_with({1: (0, 0)})
    with pytest.raises(ValueError, match="already attached"):
        medium.attach(1, FakeStack(1), lambda: (0, 0))


@pytest.mark.parametrize("offset_s, collide", [(0.0001, True), (0.0005, False)])
def test_events_collide_only_when_their_pdus_share_a_channel(offset_s, collide):
    # a 20-byte frame: three 304 us PDUs on channels 37, 38, 39; a scanner listens on one channel
    medium, stacks = medium_with({1: (-3, 0), 2: (3, 0), 3: (0, 0)})
    stacks[1].outbox.append(Tx(b"a" * 20, 1, 3))
    medium.pump(offset_s)
    stacks[2].outbox.append(Tx(b"b" * 20, 2, 3))
    medium.pump(0.1)
    assert (medium.stats.collisions == 2) is collide and len(stacks[3].heard) == (0 if collide else 2)


class DroppingStack(FakeStack):
    """A stack that drops every frame it hears (receive says False), perhaps moving its timer later
    (`timer_after_drop`), and counts the medium's asks for transmissions."""

    asked: int = 0
    timer_after_drop: float | None = None

    def receive(self, data, now, *, rssi_dbm=None, relay_delay_s=0.0):
        super().receive(data, now, rssi_dbm=rssi_dbm, relay_delay_s=relay_delay_s)
        if self.timer_after_drop is not None:
            self.timer = self.timer_after_drop
        return False

    def transmissions(self, now):
        self.asked += 1
        return super().transmissions(now)


def test_a_stack_that_dropped_a_frame_is_not_asked():
    medium = SimMedium(DiscChannel(), 7, timing=NO_JITTER)
    sender, dropper = FakeStack(1), DroppingStack(2)
    medium.attach(1, sender, lambda: (0, 0))
    medium.attach(2, dropper, lambda: (3, 0))
    for k in range(5):
        sender.outbox.append(Tx(bytes([k]) * 20, 1, 2, seq=k))
    medium.pump(1.0)
    assert len(dropper.heard) == 5 and dropper.asked == 1  # the pump's flush only


def test_a_timer_moved_later_by_a_dropped_frame_still_fires_at_its_new_time():
    medium = SimMedium(DiscChannel(), 7, timing=NO_JITTER)
    sender, dropper = FakeStack(1), DroppingStack(2)
    medium.attach(1, sender, lambda: (0, 0))
    medium.attach(2, dropper, lambda: (3, 0))
    dropper.timer = 0.5
    medium.pump(0.0)  # the medium has read the timer: 0.5
    dropper.timer_after_drop = 0.8
    sender.outbox.append(Tx(b"a" * 20, 1, 2))
    medium.pump(2.0)  # the frame arrives at ~1 ms and moves the timer; no flush in between
    assert len(dropper.heard) == 1 and dropper.fired == [0.8]


class TimerCountingStack(FakeStack):
    """Counts the medium's get_timer() asks."""

    asks: int = 0

    def get_timer(self):
        self.asks += 1
        return super().get_timer()


def test_a_timer_entry_superseded_by_an_earlier_one_fires_once_and_is_not_asked_again():
    # this used to ask the stack again when the superseded entry (0.9) came due: three asks in four
    # in the convoy of 30 were such entries
    medium = SimMedium(DiscChannel(), 7, timing=NO_JITTER)
    stack = TimerCountingStack(1)
    medium.attach(1, stack, lambda: (0, 0))
    stack.timer = 0.9
    medium.pump(0.0)  # read: an entry at 0.9
    stack.timer = 0.5
    medium.flush(0.0)  # read again: an entry at 0.5 supersedes the one at 0.9
    asks = stack.asks
    medium.pump(2.0)
    assert stack.fired == [0.5]
    # the pump's flush, then at 0.5 whether it is due and the timer after handling it; none at 0.9
    assert stack.asks == asks + 3
