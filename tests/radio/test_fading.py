"""radio/fading.py: the Rician power gain of one frame."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from rescuemesh.radio.fading import gain_db_distribution, rician_cdf, rician_gain_from_uniforms, rician_gains


@pytest.mark.parametrize("k", [0.0, 1.0, 5.0, 30.0])
def test_mean_gain_is_one(k):
    g = rician_gains(np.random.default_rng(1), k, 200_000)
    assert g.mean() == pytest.approx(1.0, abs=0.01)
    assert np.all(g >= 0.0)


def test_rayleigh_is_exponential():
    g = rician_gains(np.random.default_rng(2), 0.0, 50_000)
    assert stats.kstest(g, "expon").pvalue > 1e-3
    x = np.array([0.01, 0.3, 1.0, 3.0])
    np.testing.assert_allclose(rician_cdf(x, 0.0), 1.0 - np.exp(-x), rtol=1e-10)


@pytest.mark.parametrize("k", [0.0, 5.0])
def test_scalar_draw_follows_the_cdf(k):
    u = np.random.default_rng(3).random((20_000, 2))
    g = np.array([rician_gain_from_uniforms(a, b, k) for a, b in u])
    assert g.mean() == pytest.approx(1.0, abs=0.02)
    assert stats.kstest(g, lambda x: rician_cdf(x, k)).pvalue > 1e-3


def test_larger_k_fades_less():
    spread = [np.std(rician_gains(np.random.default_rng(4), k, 50_000)) for k in (0.0, 1.0, 5.0, 30.0)]
    assert spread == sorted(spread, reverse=True)
    assert spread[0] == pytest.approx(1.0, abs=0.02)  # exponential: std = mean


@pytest.mark.parametrize("k", [0.0, 5.0])
def test_db_distribution_is_a_probability_with_mean_gain_one(k):
    x_db, mass = gain_db_distribution(k)
    assert mass.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(mass >= 0)
    assert np.sum(mass * 10 ** (x_db / 10)) == pytest.approx(1.0, abs=2e-3)
    median = x_db[np.searchsorted(np.cumsum(mass), 0.5)]
    expected = 10 * math.log10(math.log(2)) if k == 0 else None  # Rayleigh median gain ln 2
    if expected is not None:
        assert median == pytest.approx(expected, abs=0.02)
