"""radio/channel.py: the interface, the BLE airtime, the disc model and the registry."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.radio import (
    CHANNELS,
    DEFAULT_CHANNEL,
    BleChannel,
    ChannelModel,
    DiscChannel,
    LossCause,
    Reception,
    ble_adv_airtime_s,
    make_channel,
)


@pytest.mark.parametrize(("frame_bytes", "airtime_us"), [(0, 3 * 18 * 8), (20, 912), (29, 1128)])
def test_airtime_is_three_advertising_pdus(frame_bytes, airtime_us):
    # (18 + N) bytes per channel at 1 Mbit/s, on channels 37, 38 and 39
    assert ble_adv_airtime_s(frame_bytes) == pytest.approx(airtime_us * 1e-6, rel=1e-12)
    assert DiscChannel().airtime_s(frame_bytes) == BleChannel().airtime_s(frame_bytes) == ble_adv_airtime_s(frame_bytes)


def test_airtime_of_a_full_frame_is_the_anchors_1_1_ms():
    assert ble_adv_airtime_s(29) == pytest.approx(1.1e-3, abs=0.05e-3)
    with pytest.raises(ValueError):
        ble_adv_airtime_s(-1)


def test_disc_delivers_inside_the_range_only():
    disc = DiscChannel(range_m=10.0)
    rng = np.random.default_rng(0)
    inside = disc.reception((0.0, 0.0), (6.0, 8.0), 20, rng)  # exactly 10 m
    assert inside == Reception(True, 0.0, None)
    outside = disc.reception((0.0, 0.0), (6.0, 8.01), 20, rng)
    assert outside.delivered is False and outside.cause is LossCause.OUT_OF_RANGE
    assert outside.rssi_dbm == -math.inf
    assert disc.audible((0.0, 0.0), (10.0, 0.0)) and not disc.audible((0.0, 0.0), (10.01, 0.0))
    assert disc.delivery_probability((0, 0), (3, 4), 20) == 1.0
    assert disc.delivery_probability((0, 0), (30, 4), 20) == 0.0
    assert disc.mean_rx_power_dbm((0, 0), (3, 4)) == 0.0
    assert disc.mean_rx_power_dbm((0, 0), (30, 4)) == -math.inf


def test_disc_ignores_walls_and_draws_nothing():
    office = load_map(office_map_path())
    disc = make_channel("disc", grid=office.grid, seed=3)
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert disc.reception((5.0, 8.0), (14.5, 8.0), 20, rng).delivered  # 9.5 m through two walls
    assert rng.bit_generator.state == state


def test_disc_maps_match_the_scalar_calls():
    disc = DiscChannel(range_m=4.0)
    pts = np.random.default_rng(1).uniform(-6, 6, size=(300, 2))
    np.testing.assert_array_equal(disc.delivery_probability_map((0.0, 0.0), pts, 20),
                                  [disc.delivery_probability((0.0, 0.0), tuple(p), 20) for p in pts])
    np.testing.assert_array_equal(disc.mean_rx_power_map((0.0, 0.0), pts),
                                  [disc.mean_rx_power_dbm((0.0, 0.0), tuple(p)) for p in pts])


def test_base_class_maps_fall_back_to_scalar_calls():
    class Half(DiscChannel):
        name = "half"

        def delivery_probability(self, tx_xy, rx_xy, frame_bytes):
            return 0.5

    pts = np.array([[1.0, 0.0], [2.0, 0.0]])
    assert ChannelModel.delivery_probability_map(Half(), (0, 0), pts, 20).tolist() == [0.5, 0.5]
    assert ChannelModel.mean_rx_power_map(Half(), (0, 0), pts).tolist() == [0.0, 0.0]


@pytest.mark.parametrize("range_m", [0.0, -5.0, math.inf, math.nan])
def test_disc_refuses_bad_ranges(range_m):
    with pytest.raises(ValueError):
        DiscChannel(range_m=range_m)


def test_registry_knows_disc_and_ble_and_ble_is_the_default():
    assert CHANNELS["disc"] is DiscChannel
    assert CHANNELS["ble"] is BleChannel
    assert DEFAULT_CHANNEL in CHANNELS
    assert isinstance(make_channel("disc", range_m=5.0), DiscChannel)
    assert make_channel("disc", range_m=5.0).range_m == 5.0
    assert isinstance(make_channel("ble", grid=None, seed=1), BleChannel)


@pytest.mark.parametrize(("name", "params", "message"), [
    ("ble-mesh", {}, "known: ble, disc"),
    ("range-loss", {"loss": 0.1}, "unknown channel model 'range-loss'"),
    ("disc", {"loss": 0.1}, "accepted: range_m"),
    ("ble", {"range_m": 10.0}, "has no parameter 'range_m'"),
    ("ble", {"shadowing_sigma_db": -1.0}, "shadowing_sigma_db must be >= 0"),
    ("ble", {"path_loss_exponent": 0.0}, "path_loss_exponent must be > 0"),
    ("ble", {"tx_power_dbm": "loud"}, "tx_power_dbm must be a number"),
    ("ble", {"sensitivity_dbm": math.nan}, "sensitivity_dbm must be finite"),
    ("disc", {"range_m": -1.0}, "range must be"),
])
def test_make_channel_errors_name_the_problem(name, params, message):
    with pytest.raises(ValueError, match=message):
        make_channel(name, grid=None, seed=0, **params)


@pytest.mark.parametrize("name", sorted(CHANNELS))
def test_settings_are_json_and_name_the_model(name):
    channel = make_channel(name, grid=load_map(office_map_path()).grid, seed=4)
    settings = channel.settings()
    assert settings["name"] == name
    assert json.loads(json.dumps(settings)) == settings
    assert name in channel.describe()


def test_reception_is_immutable():
    r = Reception(True, -60.0, None)
    with pytest.raises(AttributeError):
        r.delivered = False  # type: ignore[misc]
    assert {c.value for c in LossCause} == {"out_of_range", "below_sensitivity", "bit_errors", "collision", "extra_loss",
                                           "radio_off", "half_duplex"}
