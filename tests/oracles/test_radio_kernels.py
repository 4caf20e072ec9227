"""The compiled radio kernels (fading, packet error, counter-based draws) give the numbers of their
Python oracles (oracles/radio.py) on random and boundary inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oracles import radio as ref
from rescuemesh.radio.fading import rician_gain_from_uniforms
from rescuemesh.radio.per import crc_covered_bits, packet_error_rate_scalar
from rescuemesh.radio.streams import counter_key, counter_uniform, splitmix64


@pytest.mark.parametrize("k", [0.0, 0.5, 5.0, 40.0])
def test_rician_gain_is_the_oracles(k):
    rng = np.random.default_rng(1)
    edges = [0.0, 1e-300, 0.5, 1.0 - 2.0**-53]
    pairs = [(a, b) for a in edges for b in edges] + [tuple(u) for u in rng.random((2000, 2))]
    for u_radius, u_angle in pairs:
        got, want = rician_gain_from_uniforms(u_radius, u_angle, k), ref.rician_gain_from_uniforms(u_radius, u_angle, k)
        assert got == pytest.approx(want, rel=1e-12, abs=1e-300), (u_radius, u_angle, k)


def test_packet_error_rate_is_the_oracles():
    rng = np.random.default_rng(2)
    margins = [-80.0, -20.0, 0.0, 2.0, 30.0, 60.0, math.inf, -math.inf, *rng.uniform(-30.0, 40.0, 3000)]
    for margin in margins:
        for frame_bytes in (0, 10, 20, 29):
            bits = crc_covered_bits(frame_bytes)
            got, want = packet_error_rate_scalar(margin, bits), ref.packet_error_rate_scalar(margin, bits)
            assert got == pytest.approx(want, rel=1e-12, abs=1e-300), (margin, bits)


def test_counter_draws_are_splitmix64_on_the_key_words():
    rng = np.random.default_rng(3)
    words = [0, 1, 2**63, 2**64 - 1, *(int(x) for x in rng.integers(0, 2**63, 200))]
    for z in words:
        assert int(splitmix64(np.uint64(z))) == ref.splitmix64(z)
    for _ in range(300):
        seed = int(rng.integers(0, 2**63))
        purpose, a, b, counter = (int(x) for x in rng.integers(0, 1 << 20, 4))
        key = counter_key(np.uint64(seed), purpose, a, b, counter)
        assert int(key) == ref.counter_key(seed, purpose, a, b, counter)
        for j in range(3):
            assert counter_uniform(key, j) == ref.counter_uniform(int(key), j)


def test_counter_uniforms_are_uniform_and_independent_of_their_neighbours():
    # a hash that ignored a key word would give equal numbers for keys differing only there
    draws = np.array([[counter_uniform(counter_key(np.uint64(5), 2, 1, b, c), 0) for c in range(400)]
                      for b in range(2, 27)])
    assert 0.0 <= draws.min() and draws.max() < 1.0
    assert abs(draws.mean() - 0.5) < 0.01 and abs(draws.var() - 1 / 12) < 0.003
    assert abs(np.corrcoef(draws[:, :-1].ravel(), draws[:, 1:].ravel())[0, 1]) < 0.03
    assert abs(np.corrcoef(draws[:-1].ravel(), draws[1:].ravel())[0, 1]) < 0.03
