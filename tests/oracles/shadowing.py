"""Oracle of the shadow field: ShadowField.unit and its node values as Python computed them before the
field was compiled (radio/shadowing.py `field_unit`), kept verbatim but for taking the field from
outside and caching nothing."""

from __future__ import annotations

import math

from rescuemesh.radio.shadowing import _MASK, _TWO_53, _splitmix64


def node_value(field, i: int, j: int) -> float:
    h = _splitmix64(_splitmix64(field._key ^ (i & _MASK)) ^ (j & _MASK))
    h1 = _splitmix64(h)
    h2 = _splitmix64(h1)
    u1 = ((h1 >> 11) + 0.5) / _TWO_53
    u2 = (h2 >> 11) / _TWO_53
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def unit(field, x: float, y: float) -> float:
    """F at (x, y) in m of ShadowField `field`."""
    gx = x / field.decorrelation_m
    gy = y / field.decorrelation_m
    i = math.floor(gx)
    j = math.floor(gy)
    u = gx - i
    v = gy - j
    w00, w10, w01, w11 = (1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v
    s = (w00 * node_value(field, i, j) + w10 * node_value(field, i + 1, j) + w01 * node_value(field, i, j + 1)
         + w11 * node_value(field, i + 1, j + 1))
    return s / math.sqrt(w00 * w00 + w10 * w10 + w01 * w01 + w11 * w11)
