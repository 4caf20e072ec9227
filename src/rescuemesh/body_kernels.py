"""A laser sweep's points in the map frame, compiled (LaserScan.points_in_map in rescuemesh/body.py).

Owns: the loop over a sweep's beams. Must not know: LaserScan, bodies, the navigation (it takes plain
arrays and numbers; it lives beside body.py, not in nav/, which imports body.py).
"""

# Every robot turns every sweep (a few hundred beams, 10 to 20 times a second) into map points: as
# numpy it was a dozen calls over the beams. The arithmetic is numpy's (cos, sin, r * c + x, in that
# order): the same points (tests/oracles/test_nav_plan_kernels.py, against tests/oracles/nav.py).

from __future__ import annotations

import math

import numpy as np
from numba import types

from rescuemesh.jit import compiled_on_first_call

_F8 = types.float64
_READONLY_F8 = types.Array(_F8, 1, "C", readonly=True)  # also takes writable arrays (the cached angles are not)


@compiled_on_first_call(_F8[:, ::1](_READONLY_F8, _READONLY_F8, _F8, _F8, _F8, _F8, _F8))
def scan_points(ranges, angles, range_min, range_max, x, y, yaw):
    """The map points (N, 2) of the beams whose range is within [range_min, range_max] (and finite),
    beam i at angles[i] + yaw from (x, y): (x + r cos a, y + r sin a)."""
    n = len(ranges)
    out = np.empty((n, 2))
    finite_only = not math.isfinite(range_max)
    m = 0
    for i in range(n):
        r = ranges[i]
        if not (r >= range_min and r <= range_max):
            continue
        if finite_only and not math.isfinite(r):
            continue
        a = angles[i] + yaw
        out[m, 0] = r * math.cos(a) + x
        out[m, 1] = r * math.sin(a) + y
        m += 1
    return out[:m]
