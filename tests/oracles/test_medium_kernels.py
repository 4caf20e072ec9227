"""The medium's compiled reception kernels make the decisions of their oracle (oracles/medium.py,
the per-receiver Python loops they replaced) on random inputs and on inputs recorded from a medium
running a BLE channel on the office map."""

from __future__ import annotations

import numpy as np
import pytest

from oracles import medium as ref
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.radio import BleChannel, DiscChannel
from rescuemesh.transport import medium_kernels as k
from rescuemesh.transport.sim_medium import AirTiming, SimMedium

BROADCAST = 0xFF


def _random_case(rng, n):
    addresses = rng.permutation(np.arange(1, 200))[:n].astype(np.int64)
    enabled = rng.random(n) < 0.85
    on_air_until = rng.choice([-np.inf, 0.5, 1.0], n, p=[0.8, 0.1, 0.1])  # 0.5: ends as the frame starts
    mean = rng.uniform(-125.0, -60.0, n)  # around the BLE floor (-113 dBm) and sensitivity (-93)
    mean[rng.random(n) < 0.05] = -np.inf
    return addresses, enabled, on_air_until, mean


def _open(law, sender, addresses, enabled, on_air_until, mean, dst, seed, counter, relayed=False):
    n = len(addresses)
    state, rssi, ok = np.empty(n, dtype=np.int8), np.empty(n), np.empty(n, dtype=np.int8)
    counts = np.zeros(k.N_COUNTS, dtype=np.int64)
    heard = k.open_receptions(sender, addresses, enabled, on_air_until, mean, 0.5, dst, BROADCAST, 200,
                              law.floor_dbm, law.fading, law.rician_k, law.packet_errors, law.sensitivity_dbm,
                              np.uint64(seed), counter, relayed, state, rssi, ok, counts)
    return heard, state, rssi, ok, counts


def _check_open(law, sender, addresses, enabled, on_air_until, mean, dst, seed, counter, relayed=False):
    heard, state, rssi, ok, counts = _open(law, sender, addresses, enabled, on_air_until, mean, dst, seed, counter,
                                           relayed)
    want_counts = np.zeros(k.N_COUNTS, dtype=np.int64)
    want_state, want_rssi, want_ok = ref.open_receptions(sender, addresses.tolist(), enabled.tolist(),
                                                         on_air_until.tolist(), mean.tolist(), 0.5, dst, BROADCAST,
                                                         200, law, seed, counter, want_counts, relayed)
    assert state.tolist() == want_state
    assert heard == sum(s != k.NOT_RECEIVER for s in want_state)
    receivers = state != k.NOT_RECEIVER
    assert ok[receivers].tolist() == [want_ok[r] for r in np.flatnonzero(receivers)]
    np.testing.assert_allclose(rssi[receivers], [want_rssi[r] for r in np.flatnonzero(receivers)], rtol=1e-12)
    assert counts.tolist() == want_counts.tolist()
    return state, rssi, ok


LAWS = {"ble": k.reception_law(BleChannel()), "disc": k.reception_law(DiscChannel())}


@pytest.mark.parametrize("law", LAWS.values(), ids=LAWS.keys())
def test_opening_receptions_is_the_oracles_on_random_inputs(law):
    rng = np.random.default_rng(11)
    for case in range(300):
        n = int(rng.integers(2, 40))
        addresses, enabled, on_air_until, mean = _random_case(rng, n)
        if law is LAWS["disc"]:
            mean = np.where(mean > -100.0, 0.0, -np.inf)
        sender = int(rng.integers(n))
        dst = BROADCAST if case % 3 else int(addresses[rng.integers(n)])
        _check_open(law, sender, addresses, enabled, on_air_until, mean, dst, int(rng.integers(2**63)), case,
                    relayed=bool(case % 2))


def test_collisions_and_settling_are_the_oracles_on_random_inputs():
    rng = np.random.default_rng(12)
    law = LAWS["ble"]
    for case in range(300):
        n = int(rng.integers(2, 40))
        addresses, enabled, on_air_until, mean = _random_case(rng, n)
        a = _check_open(law, 0, addresses, enabled, on_air_until, mean, BROADCAST, 7, case)
        b = _check_open(law, n - 1, addresses, enabled, on_air_until, mean + rng.normal(0, 15, n), BROADCAST, 7, case)
        want_a, want_b = a[0].tolist(), b[0].tolist()
        ref.collide(want_a, a[1].tolist(), want_b, b[1].tolist(), 21.0)
        k.collide(a[0], a[1], b[0], b[1], 21.0)
        assert a[0].tolist() == want_a and b[0].tolist() == want_b
        enabled_now = enabled & (rng.random(n) < 0.9)
        extra = float(rng.choice([0.0, 0.2, 0.6]))
        dst = BROADCAST if case % 2 else int(addresses[rng.integers(n)])
        counts, want_counts = np.zeros(k.N_COUNTS, dtype=np.int64), np.zeros(k.N_COUNTS, dtype=np.int64)
        delays = np.full(n, np.nan)
        relayed = bool(case % 3 == 0)
        got = k.close_receptions(0, addresses, enabled_now, a[0], a[2], dst, BROADCAST, extra, 0.01, np.uint64(7),
                                 case, relayed, delays, counts)
        want_state, want_delays, *want = ref.close_receptions(0, addresses.tolist(), enabled_now.tolist(), want_a,
                                                              a[2].tolist(), dst, BROADCAST, extra, 0.01, 7, case,
                                                              want_counts, relayed)
        assert list(got) == want
        assert a[0].tolist() == want_state and counts.tolist() == want_counts.tolist()
        for r, delay in want_delays.items():
            assert delays[r] == delay


class _Stack:
    """Sends a broadcast every few timer ticks; hears everything."""

    def __init__(self, address):
        self.address, self.timer, self.sent = address, 0.001 * address, 0

    def receive(self, data, now, *, rssi_dbm=None, relay_delay_s=0.0):
        return False

    def transmissions(self, now):
        return []

    def get_timer(self):
        return self.timer

    def handle_timer(self, now):
        self.timer = now + 0.013 + 0.001 * (self.address % 5)


def test_the_kernels_are_the_oracles_on_inputs_recorded_from_a_running_medium(monkeypatch):
    office = load_map(office_map_path())
    channel = BleChannel(office.grid, seed=3)
    medium = SimMedium(channel, 3, extra_loss=0.2, timing=AirTiming(), record=True)
    seen = {"open": 0, "close": 0, "collide": 0}
    opened, closed, collided = k.open_receptions, k.close_receptions, k.collide

    def open_checked(sender, addresses, enabled, on_air, mean, start, dst, broadcast, bits, floor, fading, rician_k,
                     packet_errors, sens, seed, counter, relayed, state, rssi, ok, counts):
        want_counts = counts.copy()
        want = ref.open_receptions(sender, addresses.tolist(), enabled.tolist(), on_air.tolist(), mean.tolist(),
                                   start, dst, broadcast, bits, medium.law, int(seed), counter, want_counts, relayed)
        heard = opened(sender, addresses, enabled, on_air, mean, start, dst, broadcast, bits, floor, fading, rician_k,
                       packet_errors, sens, seed, counter, relayed, state, rssi, ok, counts)
        assert state.tolist() == want[0] and counts.tolist() == want_counts.tolist()
        seen["open"] += 1
        return heard

    def collide_checked(state, rssi, other_state, other_rssi, capture):
        want_a, want_b = state.tolist(), other_state.tolist()
        ref.collide(want_a, rssi.tolist(), want_b, other_rssi.tolist(), capture)
        collided(state, rssi, other_state, other_rssi, capture)
        assert state.tolist() == want_a and other_state.tolist() == want_b
        seen["collide"] += 1

    def close_checked(sender, addresses, enabled, state, ok, dst, broadcast, extra, delay_max, seed, counter, relayed,
                      delays, counts):
        want_counts = counts.copy()
        want = ref.close_receptions(sender, addresses.tolist(), enabled.tolist(), state.tolist(), ok.tolist(), dst,
                                    broadcast, extra, delay_max, int(seed), counter, want_counts, relayed)
        got = closed(sender, addresses, enabled, state, ok, dst, broadcast, extra, delay_max, seed, counter, relayed,
                     delays, counts)
        assert list(got) == list(want[2:]) and state.tolist() == want[0] and counts.tolist() == want_counts.tolist()
        seen["close"] += 1
        return got

    monkeypatch.setattr(k, "open_receptions", open_checked)
    monkeypatch.setattr(k, "collide", collide_checked)
    monkeypatch.setattr(k, "close_receptions", close_checked)
    rng = np.random.default_rng(4)
    free = np.argwhere(~office.grid.occupied)
    places = {}
    for address in range(1, 13):
        row, col = free[rng.integers(len(free))]
        places[address] = office.grid.cell_to_world(int(row), int(col))
        medium.attach(address, _Sender(address), lambda a=address: places[a])
    for tick in range(40):
        medium.pump(0.05 * tick)
    assert seen["open"] > 100 and seen["close"] > 100 and seen["collide"] > 10, seen


class _Sender(_Stack):
    def handle_timer(self, now):
        super().handle_timer(now)
        self.sent += 1

    def transmissions(self, now):
        if self.sent:
            self.sent = 0
            return [_Tx(bytes(18), self.address)]
        return []


class _Tx:
    def __init__(self, data, src):
        self.data, self.src, self.dst, self.msg_type = data, src, BROADCAST, 34
        self.relayed, self.segment, self.seq = False, None, 0


@pytest.mark.parametrize("margin_db", [-3.0, 0.0, 2.0, 6.0])
def test_the_counter_draws_deliver_as_often_as_the_channel_expects(margin_db):
    # the statistics did not change with the draws: over many transmissions of one pair, the
    # kernel's delivered fraction is the channel's expected delivery (fading and PER)
    channel = BleChannel()
    law = k.reception_law(channel)
    addresses, enabled, on_air = np.array([1, 2], dtype=np.int64), np.ones(2, dtype=bool), np.full(2, -np.inf)
    mean = np.array([-np.inf, law.sensitivity_dbm + margin_db])
    n, delivered = 8_000, 0
    for counter in range(n):
        delivered += int(_open(law, 0, addresses, enabled, on_air, mean, BROADCAST, 9, counter)[3][1] == k.OK)
    expected = channel.delivery_at_margin(margin_db, 200 // 8 - 13)
    assert abs(delivered / n - expected) < 4.0 * np.sqrt(expected * (1 - expected) / n) + 1e-3
