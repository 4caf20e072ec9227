"""Oracles of the radio kernels: the Python that radio/fading.py, radio/per.py and radio/streams.py
compiled (the first two verbatim from before), and SplitMix64 on Python ints."""

from __future__ import annotations

import math

from rescuemesh.radio.per import GAMMA_AT_SENSITIVITY

TWO_PI = 2.0 * math.pi
_M64 = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15


def rician_gain_from_uniforms(u_radius: float, u_angle: float, k: float) -> float:
    r2 = -2.0 * math.log(1.0 - u_radius)
    if k == 0.0:
        return 0.5 * r2
    scale = 1.0 / (2.0 * (k + 1.0))
    r = math.sqrt(r2 * scale)
    re = math.sqrt(k / (k + 1.0)) + r * math.cos(TWO_PI * u_angle)
    im = r * math.sin(TWO_PI * u_angle)
    return re * re + im * im


def packet_error_rate_scalar(margin_db: float, bits: int) -> float:
    exponent = 0.5 * GAMMA_AT_SENSITIVITY * 10.0 ** (margin_db / 10.0)
    if exponent > 700.0:
        return 0.0
    ber = 0.5 * math.exp(-exponent)
    return -math.expm1(bits * math.log1p(-ber))


def splitmix64(z: int) -> int:
    z = (z + _GOLDEN) & _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def counter_key(seed: int, purpose: int, a: int, b: int, counter: int) -> int:
    x = splitmix64(seed & _M64)
    for word in (purpose, a, b, counter):
        x = splitmix64(x ^ (word & _M64))
    return x


def counter_uniform(key: int, j: int) -> float:
    return (splitmix64(key ^ ((j * _GOLDEN) & _M64)) >> 11) * 2.0**-53
