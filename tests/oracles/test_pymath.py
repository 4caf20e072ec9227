"""rescuemesh/pymath.py's compiled hypot against CPython's math.hypot (not libm's): the same number, bit
for bit, for two and three coordinates, on random, tiny, huge, subnormal and special values."""

import math

import numpy as np

from rescuemesh.jit import compiled
from rescuemesh.pymath import py_hypot, py_hypot3


def _coordinates(rng, n):
    """n values of each kind the kernels may meet or that tests the algorithm's branches, then specials."""
    return np.concatenate([rng.uniform(-10, 10, n), rng.normal(0, 1e-3, n), np.round(rng.uniform(-50, 50, n), 2),
                           np.exp(rng.uniform(-700, 700, n)) * rng.choice([-1, 1], n),
                           rng.uniform(-1, 1, n) * 10.0 ** rng.integers(-320, -300, n)])


_SPECIAL = [0.0, -0.0, math.inf, -math.inf, math.nan, 5e-324, 1.7976931348623157e308, 3.0, 4.0]


@compiled()
def _many2(a, b):
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = py_hypot(a[i], b[i])
    return out


@compiled()
def _many3(a, b, c):
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = py_hypot3(a[i], b[i], c[i])
    return out


def test_py_hypot_is_pythons_hypot_not_libms():
    # a two-vertex polyline's arc length is hypot(dx, dy), in the compiled controller's own arithmetic
    rng = np.random.default_rng(40)
    sa, sb = np.meshgrid(_SPECIAL, _SPECIAL)
    a = np.concatenate([_coordinates(rng, 40_000), sa.ravel()])
    b = np.concatenate([_coordinates(rng, 40_000)[rng.permutation(200_000)], sb.ravel()])
    want = np.array([math.hypot(x, y) for x, y in zip(a.tolist(), b.tolist())])
    np.testing.assert_array_equal(_many2(a, b), want)
    with np.errstate(over="ignore"):
        assert (np.hypot(a, b) != want).sum() > 50  # libm's hypot, which numba's math.hypot calls, differs


def test_py_hypot3_is_pythons_three_argument_hypot():
    # the link budget's antenna distance: hypot(dx, dy, the antennas' height difference)
    rng = np.random.default_rng(41)
    sa, sb, sc = np.meshgrid(_SPECIAL, _SPECIAL, _SPECIAL)
    a = np.concatenate([_coordinates(rng, 20_000), sa.ravel()])
    b = np.concatenate([_coordinates(rng, 20_000)[rng.permutation(100_000)], sb.ravel()])
    c = np.concatenate([_coordinates(rng, 20_000)[rng.permutation(100_000)], sc.ravel()])
    c[:5_000] = rng.choice([0.0, 0.3, 1.2], 5_000)  # heights as the channel has them
    want = np.array([math.hypot(x, y, z) for x, y, z in zip(a.tolist(), b.tolist(), c.tolist())])
    np.testing.assert_array_equal(_many3(a, b, c), want)
    two = np.array([math.hypot(x, y) for x, y in zip(a.tolist(), b.tolist())])
    np.testing.assert_array_equal(_many3(a, b, np.zeros_like(a)), two)  # a third 0 changes nothing
