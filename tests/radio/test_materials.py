"""radio/materials.py: wall losses from ITU-R P.2040 material properties, and BleParams' defaults."""

from __future__ import annotations

import math

import pytest

from rescuemesh.maps import WallMaterial
from rescuemesh.radio import BleParams
from rescuemesh.radio.materials import P2040_TABLE3, slab_loss_db, wall_loss_db


def test_the_defaults_are_the_p2040_slabs_at_2440_mhz():
    p = BleParams()
    for material in WallMaterial:
        assert getattr(p, f"wall_loss_{material.value}_db") == pytest.approx(wall_loss_db(material, 2440.0), abs=0.05)
    assert p.wall_loss_db == p.wall_loss_brick_db  # an untagged wall is an interior brick wall


def test_losses_fall_in_the_measured_ranges():
    # 2.4 GHz: plasterboard 1-3 dB, brick 3-8 dB, concrete 8-15 dB (COST 231 4.7; NIST 1997)
    assert 1.0 <= wall_loss_db(WallMaterial.LIGHT, 2440.0) <= 3.0
    assert 3.0 <= wall_loss_db(WallMaterial.BRICK, 2440.0) <= 8.0
    assert 8.0 <= wall_loss_db(WallMaterial.CONCRETE, 2440.0) <= 15.0


def test_slab_physics():
    assert slab_loss_db("concrete", 0.0, 2440.0) == pytest.approx(0.0, abs=1e-12)
    losses = [slab_loss_db("concrete", t, 2440.0) for t in (0.05, 0.1, 0.2, 0.3)]
    assert losses == sorted(losses)  # a lossy slab: thicker costs more
    # a thick slab's loss grows by the material's attenuation: 8.686 * k0 * Im(sqrt(eta)) dB per m
    eta = P2040_TABLE3["concrete"].permittivity(2.44)
    per_m = 8.686 * 2 * math.pi * 2.44e9 / 299_792_458.0 * abs((eta ** 0.5).imag)
    assert slab_loss_db("concrete", 1.0, 2440.0) - slab_loss_db("concrete", 0.5, 2440.0) == \
        pytest.approx(0.5 * per_m, rel=0.02)


def test_outside_the_tables_frequencies_is_refused():
    with pytest.raises(ValueError, match="brick"):
        slab_loss_db("brick", 0.1, 60_000.0)
    with pytest.raises(ValueError):
        slab_loss_db("brick", -0.1, 2440.0)
