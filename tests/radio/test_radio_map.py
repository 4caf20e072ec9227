"""report/radio_map.py: the radio map PNG (tests mirror the radio package it draws)."""

from __future__ import annotations

import pytest

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.radio import make_channel
from rescuemesh.report.radio_map import RadioMapQuantity, write_radio_map

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def office():
    return load_map(office_map_path())


@pytest.mark.parametrize(("name", "quantity"), [("ble", "delivery"), ("ble", RadioMapQuantity.POWER),
                                                ("disc", "delivery")])
def test_writes_a_png(office, tmp_path, name, quantity):
    channel = make_channel(name, grid=office.grid, seed=0)
    out = write_radio_map(office, channel, (3.0, 4.6), tmp_path / "radio_map.png", quantity=quantity)
    assert out == tmp_path / "radio_map.png"
    data = out.read_bytes()
    assert data.startswith(PNG_SIGNATURE) and len(data) > 20_000


@pytest.mark.parametrize(("tx", "message"), [
    ((9.05, 2.0), "inside a wall or obstacle"),  # the hall's east wall
    ((2.2, 2.2), "inside a wall or obstacle"),  # the pillar
    ((25.0, 4.0), "off the map"),
    ((-0.5, 4.0), "off the map"),
])
def test_refuses_a_transmitter_in_a_wall_or_off_the_map(office, tmp_path, tx, message):
    channel = make_channel("ble", grid=office.grid, seed=0)
    with pytest.raises(ValueError, match=message):
        write_radio_map(office, channel, tx, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_refuses_an_unknown_quantity(office, tmp_path):
    with pytest.raises(ValueError, match="known: delivery, power"):
        write_radio_map(office, make_channel("disc"), (3.0, 4.6), tmp_path / "x.png", quantity="snr")
