"""BleChannel's row call and the Fresnel kernel that skips free space give the numbers of the scalar
link budget and of the kernel before it (oracles/walls.py), on the office and a SLAM-like map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from oracles import walls as ref
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.maps.slam_like import write_slam_like_map
from rescuemesh.radio.ble import BleChannel
from rescuemesh.radio.walls import _occupied_sat, _padded, _padded_codes, _wall_loss_skipping, _fresnel_wall_loss

_LAMBDA = 0.1229


@pytest.fixture(scope="module", params=["office", "slam_like"])
def grid(request, tmp_path_factory):
    if request.param == "office":
        return load_map(office_map_path()).grid
    return load_map(write_slam_like_map(Path(tmp_path_factory.mktemp("slam")))).grid


def _places(grid, rng, n):
    """Random points over the map and a little beyond it, a share of them inside occupied cells,
    and some pairs of coincident points (same point, same cell)."""
    h, w = grid.occupied.shape
    res = grid.resolution
    x0, y0 = grid.origin_x - 0.5, grid.origin_y - 0.5
    pts = np.column_stack([rng.uniform(x0, x0 + w * res + 1.0, n), rng.uniform(y0, y0 + h * res + 1.0, n)])
    rows, cols = np.nonzero(grid.occupied)
    pick = rng.integers(0, len(rows), n // 4)
    pts[: n // 4] = np.column_stack([grid.origin_x + (cols[pick] + rng.random(len(pick))) * res,
                                     grid.origin_y + (rows[pick] + rng.random(len(pick))) * res])
    if n >= 100:
        pts[n // 4: n // 4 + 10] = pts[:10]  # coincident with points inside walls
        pts[n // 4 + 10: n // 4 + 20] = pts[n // 2: n // 2 + 10] + res / 4  # same cell, another point
    return pts


def test_skipping_line_walk_is_the_plain_walk(grid):
    rng = np.random.default_rng(11)
    padded, sat, codes = _padded(grid), _occupied_sat(grid), _padded_codes(grid)
    table = rng.uniform(0.5, 15.0, 256)
    h, w = grid.occupied.shape
    for _ in range(20000):
        r0, r1 = rng.integers(-3, h + 3, 2)
        c0, c1 = rng.integers(-3, w + 3, 2)
        if rng.random() < 0.5:  # short segments, as the Fresnel rays' are
            r1, c1 = r0 + rng.integers(-30, 31), c0 + rng.integers(-30, 31)
        args = (int(r0), int(c0), int(r1), int(c1))
        assert _wall_loss_skipping(padded, sat, codes, table, *args) == ref.wall_loss_on_line(padded, codes, table, *args), args


@pytest.mark.parametrize(("rays", "dh"), [(9, 0.0), (9, 0.3), (5, 0.0), (1, 0.0)])
def test_fresnel_kernel_is_the_one_before_the_early_out(grid, rays, dh):
    rng = np.random.default_rng(12)
    padded, sat, codes = _padded(grid), _occupied_sat(grid), _padded_codes(grid)
    table = BleChannel(grid).params.loss_by_code
    frame = (float(grid.origin_x), float(grid.origin_y), float(grid.resolution))
    a, b = _places(grid, rng, 3000), _places(grid, rng, 3000)
    b[-300:] = a[-300:] + rng.normal(0.0, 0.4, (300, 2))  # short links, mostly in free space
    for p, q in zip(a.tolist(), b.tolist()):
        for u, v in ((p, q), (q, p)):
            got = _fresnel_wall_loss(padded, sat, codes, table, *frame, *u, *v, _LAMBDA, dh, rays)
            want = ref.fresnel_wall_loss(padded, codes, table, *frame, *u, *v, _LAMBDA, dh, rays)
            assert got == want, (u, v)


@pytest.mark.parametrize("params", [{}, {"wall_fresnel_rays": 1}, {"shadowing_sigma_db": 0.0},
                                    {"rx_antenna_height_m": 1.2, "far_path_loss_exponent": 3.0}])
def test_row_is_the_scalar_per_pair(grid, params):
    rng = np.random.default_rng(13)
    row_channel = BleChannel(grid, seed=4).with_params(**params)
    scalar = BleChannel(grid, seed=4).with_params(**params)
    rx = _places(grid, rng, 400)
    for tx in [*_places(grid, rng, 12).tolist(), rx[0].tolist(), rx[len(rx) // 4 + 12].tolist()]:
        got = row_channel.mean_rx_power_row(tx, rx)
        want = np.array([scalar.mean_rx_power_dbm(tx, tuple(p)) for p in rx.tolist()])
        assert np.array_equal(got, want), (tx, np.flatnonzero(got != want)[:5])
        back = np.array([row_channel.mean_rx_power_row(tuple(p), np.array([tx]))[0] for p in rx[:40].tolist()])
        assert np.array_equal(back, want[:40])  # the other way round: the same pair, the same number
    assert row_channel.mean_rx_power_row((1.0, 1.0), np.zeros((0, 2))).shape == (0,)


def test_row_without_a_map_is_the_scalar():
    rng = np.random.default_rng(14)
    channel = BleChannel(None, seed=2)
    rx = rng.uniform(-20.0, 20.0, (500, 2))
    got = channel.mean_rx_power_row((0.3, -0.7), rx)
    assert np.array_equal(got, [channel.mean_rx_power_dbm((0.3, -0.7), tuple(p)) for p in rx.tolist()])


def test_a_subclass_with_its_own_mean_power_is_asked_per_pair():
    class Louder(BleChannel):
        def mean_rx_power_dbm(self, tx_xy, rx_xy):
            return super().mean_rx_power_dbm(tx_xy, rx_xy) + 10.0

    rx = np.array([[1.0, 2.0], [4.0, 0.5]])
    assert np.array_equal(Louder(None).mean_rx_power_row((0.0, 0.0), rx),
                          BleChannel(None).mean_rx_power_row((0.0, 0.0), rx) + 10.0)


def test_the_medium_holds_the_scalar_mean_power_of_every_pair_as_radios_move():
    # SimMedium._mean_row asks the channel for a row of the pairs whose cell changed; this used to be
    # one mean_rx_power_dbm call per pair, whose numbers the matrix must still hold
    from rescuemesh.transport.sim_medium import SimMedium

    class Quiet:
        def receive(self, data, now, *, rssi_dbm=None, relay_delay_s=0.0):
            pass

        def transmissions(self, now):
            return []

        def get_timer(self):
            return None

        def handle_timer(self, now):
            pass

    grid = load_map(office_map_path()).grid
    channel = BleChannel(grid, seed=3)
    rng = np.random.default_rng(15)
    where = {address: tuple(p) for address, p in enumerate(_places(grid, rng, 12).tolist(), start=1)}
    medium = SimMedium(channel, 7)
    for address in where:
        medium.attach(address, Quiet(), lambda a=address: where[a])
    for step in range(4):
        medium._positions_fresh = False
        for radio in medium._order_of:
            row = medium._mean_row(radio)
            me = where[radio.address]
            for other in medium._order_of:
                if other is not radio:
                    assert row[other.index] == channel.mean_rx_power_dbm(me, where[other.address]), (step, radio.address)
        for address in list(where)[step::3]:  # some radios move to other cells
            where[address] = (where[address][0] + 0.3, where[address][1] - 0.2)


def _without_materials(grid):
    from dataclasses import replace

    return replace(grid, materials=None)


@pytest.mark.parametrize("params", [{}, {"wall_fresnel_rays": 1}, {"shadowing_sigma_db": 0.0},
                                    {"rx_antenna_height_m": 1.2, "far_path_loss_exponent": 3.0},
                                    {"wall_fresnel_rays": 1, "no_materials": True}, {"no_map": True}])
def test_budget_terms_are_the_python_budget_they_replaced(grid, params):
    # the scalar link budget used to be Python beside the compiled row (two implementations of one
    # budget); it now calls the row for one receiver, and must give every term the Python gave
    from oracles.ble_budget import budget_terms

    params = dict(params)
    on = None if params.pop("no_map", False) else (_without_materials(grid) if params.pop("no_materials", False)
                                                   else grid)
    channel = BleChannel(on, seed=5).with_params(**params)
    rng = np.random.default_rng(16)
    a, b = _places(grid, rng, 600), _places(grid, rng, 600)
    b[-100:] = a[-100:] + rng.normal(0.0, 0.3, (100, 2))
    for p, q in zip(a.tolist(), b.tolist()):
        lo, hi = sorted((channel._cell(p), channel._cell(q)))
        got = channel._budget_terms(*lo, *hi)
        want = budget_terms(channel, *lo, *hi)
        assert got == want, (p, q, got, want)
        assert type(got[2]) is int
        budget = channel.link_budget(p, q)
        assert (budget.distance_m, budget.walls, budget.mean_rx_power_dbm) == (want[0], want[2], want[4])


def test_the_compiled_shadow_field_is_the_python_one():
    # ShadowField.unit (and the link budget's row, which calls the same kernel) against the Python
    # field it replaced, over the plane and far from the origin, for seeds that set every key bit
    from oracles.shadowing import unit
    from rescuemesh.radio.shadowing import ShadowField

    rng = np.random.default_rng(17)
    pts = np.concatenate([rng.uniform(-60.0, 60.0, (3000, 2)), rng.uniform(-1e6, 1e6, (300, 2)),
                          np.round(rng.uniform(-20.0, 20.0, (300, 2)), 1)])  # on the lattice's lines too
    for seed, spacing in ((0, 4.0), (2**63 - 1, 4.0), (-1, 0.7), (12345, 9.5)):
        field = ShadowField(seed, 4.0, spacing)
        got = np.array([field.unit(x, y) for x, y in pts.tolist()])
        want = np.array([unit(field, x, y) for x, y in pts.tolist()])
        np.testing.assert_array_equal(got, want)
