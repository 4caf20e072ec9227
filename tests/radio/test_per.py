"""radio/per.py: the BLE bit- and packet-error curves."""

from __future__ import annotations

import numpy as np
import pytest

from rescuemesh.radio.per import (
    BER_AT_SENSITIVITY,
    bit_error_rate,
    crc_covered_bits,
    packet_error_rate,
    packet_error_rate_scalar,
)


def test_ber_is_one_per_mille_at_sensitivity():
    # Core Vol 6 Part A 4.1: sensitivity is where BER = 0.1 %
    assert bit_error_rate(0.0) == pytest.approx(BER_AT_SENSITIVITY, rel=1e-12)
    assert BER_AT_SENSITIVITY == 1e-3


def test_crc_covers_header_adva_ad_header_frame_and_crc():
    assert crc_covered_bits(20) == 8 * (2 + 6 + 2 + 20 + 3)
    assert crc_covered_bits(0) == 8 * 13
    with pytest.raises(ValueError):
        crc_covered_bits(-1)


@pytest.mark.parametrize(("frame_bytes", "expected"), [(20, 1 - 0.999 ** 264), (24, 1 - 0.999 ** 296)])
def test_per_at_sensitivity_is_about_a_quarter(frame_bytes, expected):
    per = packet_error_rate(0.0, frame_bytes)
    assert per == pytest.approx(expected, rel=1e-9)
    assert 0.2 < per < 0.3  # the brief's "about 26 %"


def test_per_is_steep_and_monotonic():
    margins = np.arange(-10.0, 10.0, 0.05)
    per = packet_error_rate(margins, 20)
    assert np.all(np.diff(per) <= 0)
    steep = (margins[:-1] > -4.0) & (margins[:-1] < 5.0)  # neither saturated at 1 nor ~0
    assert np.all(np.diff(per)[steep] < 0)
    assert packet_error_rate(2.0, 20) < 0.01
    assert packet_error_rate(-3.0, 20) > 0.99
    assert packet_error_rate(0.0, 29) > packet_error_rate(0.0, 10)  # more bits, more errors


@pytest.mark.parametrize("margin", [-20.0, -3.0, -0.5, 0.0, 0.7, 2.0, 8.0, 30.0])
def test_scalar_path_equals_vector_formula(margin):
    assert packet_error_rate_scalar(margin, crc_covered_bits(20)) == pytest.approx(
        packet_error_rate(margin, 20), rel=1e-12, abs=1e-300)
