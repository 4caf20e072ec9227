"""Log-normal shadowing that is seeded and spatially correlated: same places, same shadow.

Owns: a per-seed Gaussian random field over the plane and the symmetric shadow of a link.
Must not know: path loss, walls, frames, the medium.

Theory. Shadowing (furniture, people, clutter the wall map does not hold) is a slowly varying
random loss, log-normal with standard deviation sigma dB, correlated over a decorrelation
distance (Gudmundson, "Correlation model for shadow fading in mobile radio systems", Electronics
Letters 27(23), 1991). Here each place p gets a standard normal F(p): independent N(0, 1) values
on the nodes of a square lattice whose spacing is the decorrelation distance, bilinearly
interpolated and divided by sqrt(sum of squared weights), so F(p) stays N(0, 1) everywhere. Its
autocorrelation falls to 1/e about 0.9 spacings apart, 0.29 at one spacing, ~0 at two (measured;
tests/radio/test_shadowing.py). A link's shadow in dB is
    S(a, b) = sigma * (F(a) + F(b)) / sqrt(2),
symmetric in a and b and N(0, sigma^2) for places more than two spacings apart; it changes
smoothly as either end moves. Node values come from a counter-based hash (SplitMix64) of
(seed, node), so the field needs no bounds, no storage and no shared random stream: the same
seed gives the same field in every process, whatever else drew random numbers before.
"""

from __future__ import annotations

import math

import numpy as np

from rescuemesh.jit import compiled

_MASK = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15
_MUL1 = 0xBF58476D1CE4E5B9
_MUL2 = 0x94D049BB133111EB
#: Mixed into the seed so the shadow field is not correlated with other seed-derived streams.
_SALT = 0x5EAD0F5AD0B1E
_TWO_53 = float(1 << 53)
_SQRT2 = math.sqrt(2.0)


def _splitmix64(x: int) -> int:
    """One SplitMix64 output for state `x` (Steele, Lea and Flood, OOPSLA 2014), on Python ints."""
    z = (x + _GOLDEN) & _MASK
    z = ((z ^ (z >> 30)) * _MUL1) & _MASK
    z = ((z ^ (z >> 27)) * _MUL2) & _MASK
    return z ^ (z >> 31)


_GOLDEN_U = np.uint64(_GOLDEN)
_MUL1_U = np.uint64(_MUL1)
_MUL2_U = np.uint64(_MUL2)
_U11, _U27, _U30, _U31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)


@compiled()  # no signature: compiled into its callers
def _splitmix64_u(x):
    """_splitmix64 on a uint64 (wrapping arithmetic, as the masks of the Python ints)."""
    z = x + _GOLDEN_U
    z = (z ^ (z >> _U30)) * _MUL1_U
    z = (z ^ (z >> _U27)) * _MUL2_U
    return z ^ (z >> _U31)


@compiled()
def _node_value(key, i, j):
    """The lattice node (i, j)'s N(0, 1) value for the field's key (uint64): Box-Muller on two
    uniforms hashed from (key, i, j). The Python it was (tests/oracles/shadowing.py) gives the same
    number, bit for bit: the ints' two's complement is the uint64's, the uniforms are the same doubles
    and log, cos and sqrt are the same libm calls."""
    h = _splitmix64_u(_splitmix64_u(key ^ np.uint64(i)) ^ np.uint64(j))
    h1 = _splitmix64_u(h)
    h2 = _splitmix64_u(h1)
    u1 = (float(h1 >> _U11) + 0.5) / _TWO_53
    u2 = float(h2 >> _U11) / _TWO_53
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@compiled()
def field_unit(key, decorrelation_m, x, y):
    """F at (x, y) m of the field with `key` (ShadowField's, uint64) and lattice spacing `decorrelation_m`:
    the nodes around the point bilinearly interpolated, over the root of the sum of squared weights."""
    gx = x / decorrelation_m
    gy = y / decorrelation_m
    i = math.floor(gx)
    j = math.floor(gy)
    u = gx - i
    v = gy - j
    w00, w10, w01, w11 = (1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v
    s = (w00 * _node_value(key, i, j) + w10 * _node_value(key, i + 1, j) + w01 * _node_value(key, i, j + 1)
         + w11 * _node_value(key, i + 1, j + 1))
    return s / math.sqrt(w00 * w00 + w10 * w10 + w01 * w01 + w11 * w11)


def _splitmix64_np(x: np.ndarray) -> np.ndarray:
    """_splitmix64 on a uint64 array (wrapping arithmetic; same values)."""
    with np.errstate(over="ignore"):
        z = x + np.uint64(_GOLDEN)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(_MUL1)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(_MUL2)
    return z ^ (z >> np.uint64(31))


class ShadowField:
    """The seeded field F and the link shadow S for one run.

    - `seed`: any int; the same seed gives the same field.
    - `sigma_db`: standard deviation of S in dB; 0 disables shadowing (S = 0).
    - `decorrelation_m`: lattice spacing in m (the Gudmundson decorrelation distance, see above).
    """

    def __init__(self, seed: int, sigma_db: float, decorrelation_m: float) -> None:
        if not sigma_db >= 0.0:
            raise ValueError(f"shadowing sigma must be >= 0 dB, got {sigma_db}")
        if not decorrelation_m > 0.0:
            raise ValueError(f"shadowing decorrelation distance must be > 0 m, got {decorrelation_m}")
        self.seed = int(seed)
        self.sigma_db = float(sigma_db)
        self.decorrelation_m = float(decorrelation_m)
        self._key = _splitmix64((self.seed ^ _SALT) & _MASK)
        self.key = np.uint64(self._key)  # what the compiled field (field_unit) takes

    # --- node values ---------------------------------------------------------------------------
    def _node_values(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        h = _splitmix64_np(_splitmix64_np(self.key ^ i.astype(np.int64).astype(np.uint64))
                           ^ j.astype(np.int64).astype(np.uint64))
        h1 = _splitmix64_np(h)
        h2 = _splitmix64_np(h1)
        u1 = ((h1 >> np.uint64(11)).astype(float) + 0.5) / _TWO_53
        u2 = (h2 >> np.uint64(11)).astype(float) / _TWO_53
        return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)

    # --- the field -----------------------------------------------------------------------------
    def unit(self, x: float, y: float) -> float:
        """F at (x, y) in m: standard normal, smooth in space, fixed by the seed (`field_unit`, which the
        link budget's compiled row calls too)."""
        return field_unit(self.key, self.decorrelation_m, float(x), float(y))

    def unit_many(self, points: np.ndarray) -> np.ndarray:
        """F at each of `points` (shape (N, 2), m); equals `unit` to rounding."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        g = pts / self.decorrelation_m
        ij = np.floor(g)
        u = g[:, 0] - ij[:, 0]
        v = g[:, 1] - ij[:, 1]
        i = ij[:, 0].astype(np.int64)
        j = ij[:, 1].astype(np.int64)
        w = ((1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v)
        z = (self._node_values(i, j), self._node_values(i + 1, j),
             self._node_values(i, j + 1), self._node_values(i + 1, j + 1))
        s = w[0] * z[0] + w[1] * z[1] + w[2] * z[2] + w[3] * z[3]
        return s / np.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2 + w[3] ** 2)

    def link_db(self, a: tuple[float, float], b: tuple[float, float]) -> float:
        """S(a, b) in dB: the shadow loss of the link between places a and b (symmetric)."""
        if self.sigma_db == 0.0:
            return 0.0
        return self.sigma_db * (self.unit(a[0], a[1]) + self.unit(b[0], b[1])) / _SQRT2

    def link_db_many(self, a: tuple[float, float], points: np.ndarray) -> np.ndarray:
        """S(a, p) in dB for each of `points` (shape (N, 2))."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if self.sigma_db == 0.0:
            return np.zeros(len(pts))
        return self.sigma_db * (self.unit(float(a[0]), float(a[1])) + self.unit_many(pts)) / _SQRT2
