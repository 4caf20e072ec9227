"""Fast (multipath) fading of one frame: a Rician power gain of mean 1.

Owns: drawing the gain, its distribution, and averaging a function of received power over it.
Must not know: path loss, walls, shadowing, frames.

A frame lasts about 1 ms, much shorter than the channel's coherence time for robots moving at
walking speed (tens of ms at 2.4 GHz), so one gain holds for the whole frame and a fresh one is
drawn for the next (block fading). With a Rician K-factor K (power in the steady component over
power in the scattered ones), the complex amplitude is
    h = sqrt(K/(K+1)) + sqrt(1/(K+1)) * CN(0, 1),   gain g = |h|^2,  E[g] = 1,
and 2(K+1) g follows a non-central chi-square law with 2 degrees of freedom and non-centrality 2K.
K = 0 is Rayleigh fading (g exponential with mean 1).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import chndtr

from rescuemesh.jit import compiled

TWO_PI = 2.0 * math.pi


@compiled("f8(f8, f8, f8)")
def rician_gain_from_uniforms(u_radius: float, u_angle: float, k: float) -> float:
    """Rician power gain (mean 1) from two independent uniforms in [0, 1), by Box-Muller.

    The hot path, compiled: the medium's reception kernel calls it per reception (callable from
    Python too, as BleChannel.reception does).
    """
    r2 = -2.0 * math.log(1.0 - u_radius)  # |CN(0,1)|^2 * 2, from a uniform in (0, 1]
    if k == 0.0:
        return 0.5 * r2
    scale = 1.0 / (2.0 * (k + 1.0))  # variance of each scattered quadrature component
    r = math.sqrt(r2 * scale)
    re = math.sqrt(k / (k + 1.0)) + r * math.cos(TWO_PI * u_angle)
    im = r * math.sin(TWO_PI * u_angle)
    return re * re + im * im


def rician_gains(rng: np.random.Generator, k: float, size: int) -> np.ndarray:
    """`size` independent Rician power gains of mean 1 (vectorised; same law as above)."""
    u = rng.random((2, size))
    r2 = -2.0 * np.log1p(-u[0])
    if k == 0.0:
        return 0.5 * r2
    r = np.sqrt(r2 / (2.0 * (k + 1.0)))
    re = math.sqrt(k / (k + 1.0)) + r * np.cos(TWO_PI * u[1])
    im = r * np.sin(TWO_PI * u[1])
    return re * re + im * im


def rician_cdf(gain, k: float):
    """P(g <= gain) for the Rician power gain of mean 1 with K-factor `k` (scalar or array)."""
    g = np.maximum(np.asarray(gain, dtype=float), 0.0)
    cdf = chndtr(2.0 * (k + 1.0) * g, 2.0, 2.0 * k)
    return float(cdf) if np.ndim(cdf) == 0 else cdf


def gain_db_distribution(k: float, step_db: float = 0.01, low_db: float = -60.0,
                         high_db: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """The gain in dB, 10 log10(g), discretised: bin centres in dB and their probabilities.

    Exact bin masses from the CDF; the tails beyond [low_db, high_db] are added to the end bins
    (below -60 dB only Rayleigh has mass worth naming, 1e-6). The masses sum to 1.
    """
    edges = np.arange(low_db, high_db + 0.5 * step_db, step_db)
    cdf = rician_cdf(10.0 ** (edges / 10.0), k)
    mass = np.diff(cdf)
    mass[0] += cdf[0]
    mass[-1] += 1.0 - cdf[-1]
    return 0.5 * (edges[:-1] + edges[1:]), mass
